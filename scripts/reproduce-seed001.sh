#!/usr/bin/env bash
# Reproduces seed 001 (neural-network calibration, Legnani & Tiboni): Tables 4–5 and Fig. 7 (2-DOF SCARA,
# all seven direct schemes, three cases), 6–8 (random errors, apparent/actual error, FI), 10–12
# (Stewart platform, inverse schemes 2 and 4) and 16–18 (3-DOF SCARA, direct schemes 3 and 4), each
# beside the paper's numbers; then the three-way comparison on the RV-M2 paper scenario
# (conventional, variable D-H + FCMAC, neural network; 2200 measurements, Fig. 6 and 7 paths).
# With SEED001_SEEDS=1-20 it then runs the tables at every seed of that range and prints, per
# paper table, ours ÷ paper and how often the paper's order of the schemes holds (7.7 min for
# 1-20 on 2 cores; docs/paper-reproduction.md quotes it).
# Usage: scripts/reproduce-seed001.sh [OUT_DIR]   (default out/seed001; about 25 s after the build)
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-out/seed001}"
mkdir -p "$out"
cargo build --release --quiet
rigcal=target/release/rigcal

echo "== seed 001 tables (Table 5: Levenberg–Marquardt fits beside the paper's gradient descent; the others: gradient descent with momentum, η = 0.01, momentum 0.9, early stopping)"
$rigcal reproduce seed001 --table 5 --table 7 --table 11 --table 18 --figure 7 --out "$out"

echo "== RV-M2 paper scenario: three calibrations on the same 2200 measurements"
$rigcal compare --rig rigs/rv-m2-ideal.toml --scenario sim/paper-sim.toml --out "$out/compare-rv-m2"
echo "tables in $out, comparison table and plots in $out/compare-rv-m2"

if [ -n "${SEED001_SEEDS:-}" ]; then
  echo "== seed 001 tables over seeds $SEED001_SEEDS"
  $rigcal reproduce seed001 --seeds "$SEED001_SEEDS" --out "$out/seeds"
fi
