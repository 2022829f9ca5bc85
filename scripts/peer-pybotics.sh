#!/usr/bin/env bash
# Times `rigcal identify` against pybotics' least-squares calibration on the same recording.
# (scripts/peers.sh times rigcal against pybotics and FIGAROH together, on issue 33's structured
# recording and a UR10 series, with rigcal's median over several runs.)
#
# Install the peer once (Python 3.8+; pybotics pulls numpy, scipy and attrs):
#     pip install pybotics          # tested with pybotics 3.1.2, scipy 1.x
# Then, from the repository root:
#     scripts/peer-pybotics.sh [N_POSES] [SCENARIO...]   # default 2200, sim/paper-sim-noise.toml
# e.g. the structured recording of issue 33 beside the white-noise one:
#     scripts/peer-pybotics.sh 2200 sim/paper-sim-noise.toml benches/fixtures/structured-warm-up-rv-m2.toml
#
# What it does: builds rigcal (release), simulates one N-pose recording on the RV-M2 per
# scenario (seed 2024; the default is the paper's errors and noise), then times on each, as
# whole processes and one run each side by side:
#   1. `rigcal identify --level full` (analysis, fit, outlier search, model file);
#   2. scripts/peer_pybotics.py: the same chain as a pybotics MDH robot, 15 parameters
#      (world frame 6, link offsets/lengths/twists 8, tool length 1) fitted by
#      scipy.optimize.least_squares on pybotics' absolute position errors, as pybotics'
#      calibration example does.
# and prints both times, both fits' RMS residuals and the ratio. Not part of `cargo test`.
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-2200}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

python3 -c "import pybotics" 2>/dev/null || {
    echo "pybotics is not installed: pip install pybotics" >&2
    exit 1
}
# RIGCAL=path/to/rigcal skips the build (a binary already built, say with --all-targets).
if [ -z "${RIGCAL:-}" ]; then
    cargo build --release --quiet --bin rigcal
    RIGCAL=target/release/rigcal
fi
RIG=rigs/rv-m2-ideal.toml
now() { date +%s.%N; }
shift || true
SCENARIOS=("$@")
[ ${#SCENARIOS[@]} -gt 0 ] || SCENARIOS=(sim/paper-sim-noise.toml)

for SCENARIO in "${SCENARIOS[@]}"; do
    REC="$WORK/$(basename "$SCENARIO" .toml)"
    "$RIGCAL" simulate --rig "$RIG" --scenario "$SCENARIO" --random "$N" \
        --seed 2024 --out "$REC" >/dev/null
    echo "== $SCENARIO: $N poses"
    t0=$(now)
    "$RIGCAL" identify --rig "$RIG" --recording "$REC" --out "$WORK/model.json" \
        >"$WORK/rigcal.txt" 2>&1
    t1=$(now)
    python3 scripts/peer_pybotics.py "$REC/measurements.csv" >"$WORK/pybotics.txt"
    t2=$(now)

    rigcal_s=$(echo "$t1 - $t0" | bc -l)
    peer_s=$(echo "$t2 - $t1" | bc -l)
    printf '%-44s %8.3f s   %s\n' "rigcal identify (whole process)" "$rigcal_s" \
        "$(grep -m1 -i 'residual after' "$WORK/rigcal.txt" || true)"
    printf '%-44s %8.3f s   %s\n' "pybotics least squares (whole process)" "$peer_s" \
        "$(cat "$WORK/pybotics.txt")"
    printf 'ratio pybotics / rigcal: %.1f×\n' "$(echo "$peer_s / $rigcal_s" | bc -l)"
done
