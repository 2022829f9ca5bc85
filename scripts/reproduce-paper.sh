#!/usr/bin/env bash
# Reproduces seed 000's simulations (Figs. 6, 7 and 8) from scratch with the simulated RV-M2 of
# sim/paper-sim.toml: planning-mode division in joint and Cartesian space, FCMAC, and the four
# cases (uncalibrated, conventional, regions, FCMAC) along the paper's paths, with SVG plots.
# Usage: scripts/reproduce-paper.sh [OUT_DIR]   (default out/paper; takes well under a minute)
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-out/paper}"
mkdir -p "$out"
cargo build --release --quiet
rigcal=target/release/rigcal
rig=rigs/rv-m2-ideal.toml
sc=sim/paper-sim.toml

echo "== Fig. 6: joint-space division, the paper's settings (0.1 mm, 20 per region, c = (3,3,3))"
$rigcal calibrate --rig $rig --scenario $sc --division joint --out "$out/fig6-model.json"
$rigcal evaluate --model "$out/fig6-model.json" --scenario $sc --path fig6 --path random --out "$out/fig6"

echo "== Fig. 6 with a finer demand (0.02 mm), where the division has to split: regions vs FCMAC vs CMAC"
$rigcal calibrate --rig $rig --scenario $sc --division joint --accuracy-mm 0.02 --out "$out/fig6-fine-model.json"
$rigcal evaluate --model "$out/fig6-fine-model.json" --scenario $sc --path fig6 --out "$out/fig6-fine"
$rigcal calibrate --rig $rig --scenario $sc --division joint --accuracy-mm 0.02 --learner cmac --out "$out/fig6-fine-cmac.json"
$rigcal evaluate --model "$out/fig6-fine-cmac.json" --scenario $sc --path fig6 --out "$out/fig6-fine-cmac"

echo "== Fig. 7: Cartesian (spherical) division"
$rigcal calibrate --rig $rig --scenario $sc --division cartesian --out "$out/fig7-model.json"
$rigcal evaluate --model "$out/fig7-model.json" --scenario $sc --path fig7 --out "$out/fig7"
$rigcal calibrate --rig $rig --scenario $sc --division cartesian --accuracy-mm 0.02 --out "$out/fig7-fine-model.json"
$rigcal evaluate --model "$out/fig7-fine-model.json" --scenario $sc --path fig7 --out "$out/fig7-fine"

echo "== Fig. 8: one region on the Fig. 6 path left unmeasurable"
$rigcal calibrate --rig $rig --scenario $sc --division joint --accuracy-mm 0.02 --unmeasurable-at 92,75,-22 --out "$out/fig8-model.json"
$rigcal evaluate --model "$out/fig8-model.json" --scenario $sc --path fig6 --out "$out/fig8"

echo "plots and CSVs in $out"
