#!/usr/bin/env bash
# The UR10 pipeline on the real laser-tracker series (Fraunhofer IPA, ../shared/data/ur10-landgraf):
# rig from the URDF, the four series imported unchanged, identification on Series A at three
# levels (frames, offsets, full), each model evaluated on B, C and D with the measurement frame
# refitted per series (the tracker was set up anew per campaign), and a table of the held-out
# mean, RMS and max position error (mm) and orientation error (degrees).
#
#   scripts/ur10.sh [DATA_DIR] [OUT_DIR]
#
# DATA_DIR defaults to $UR10_DATA or ../shared/data/ur10-landgraf (beside the clone); OUT_DIR to
# target/ur10. Training: all 11 911 rows of Series A (the grid, ~20 orientations per position,
# four days). Set UR10_TRAIN_EVERY=N to train on every N-th row of A instead (a spread subset:
# every position of the grid keeps some of its orientations).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
data="${1:-${UR10_DATA:-$here/../shared/data/ur10-landgraf}}"
out="${2:-$here/target/ur10}"
every="${UR10_TRAIN_EVERY:-1}"
if [ ! -f "$data/ur10.urdf" ]; then
  echo "no UR10 data at $data (give the directory as the first argument or in UR10_DATA)" >&2
  exit 2
fi
mkdir -p "$out"
cd "$here"
cargo build --release --quiet
rigcal="$here/target/release/rigcal"

joints=shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint
"$rigcal" rig from-urdf "$data/ur10.urdf" --base base_link --tip tool0 --out "$out/ur10.toml"

import() { # series file
  "$rigcal" import "$data/Series_$1/$2" --rig "$out/ur10.toml" --joints "$joints" \
    --point measurement_x,measurement_y,measurement_z --length-unit mm --angle-unit rad \
    --orientation measurement_rx,measurement_ry,measurement_rz --euler intrinsic-xyz \
    --orientation-unit deg --temperature measurement_temperature --out "$out/rec-$1"
}
import A measurements_grid.csv
import B measurements_joint_configurations.csv
import C measurements_random_poses.csv
import D measurements_iso_cubes.csv

train="$out/rec-A"
if [ "$every" != 1 ]; then
  # Every N-th data row of A, header kept: the grid's positions stay, fewer orientations each.
  rm -rf "$out/rec-A-every$every" && mkdir -p "$out/rec-A-every$every"
  cp "$out/rec-A/session.toml" "$out/rec-A-every$every/" 2>/dev/null || true
  awk -v n="$every" 'NR == 1 || (NR - 2) % n == 0' "$out/rec-A/measurements.csv" \
    > "$out/rec-A-every$every/measurements.csv"
  train="$out/rec-A-every$every"
fi

for level in frames offsets full; do
  echo "== identify on $(basename "$train") at level $level"
  "$rigcal" identify --rig "$out/ur10.toml" --recording "$train" --level "$level" \
    --out "$out/model-$level.json" | grep -v '^outlier removed' || true
  for s in B C D; do
    "$rigcal" evaluate --model "$out/model-$level.json" --recording "$out/rec-$s" --refit-frame \
      --json "$out/eval-$level-$s.json" > "$out/eval-$level-$s.txt"
  done
done

echo
echo "UR10, trained on $(basename "$train"), held out with the measurement frame refitted per series"
echo "position error mm (mean / RMS / max), orientation error deg (RMS)"
python3 - "$out" <<'EOF'
import json, sys
out = sys.argv[1]
rows = []
def fmt(s):
    p = s["position"]; o = s.get("orientation")
    return "%.3f / %.3f / %.3f" % (p["mean_mm"], p["rms_mm"], p["max_mm"]) + \
        ("  %.4f°" % o["rms_deg"] if o else "")
print("| level | " + " | ".join("Series %s" % s for s in "BCD") + " |")
print("|---|---|---|---|")
nominal = []
for s in "BCD":
    e = json.load(open("%s/eval-full-%s.json" % (out, s)))
    nominal.append(e)
print("| nominal, frame refitted | " + " | ".join(fmt(e["scores"][0]) for e in nominal) + " |")
print("| nominal, frame + marker refitted (in sample) | " + " | ".join(fmt(e["scores"][1]) for e in nominal) + " |")
for level in ("frames", "offsets", "full"):
    cells = []
    for s in "BCD":
        e = json.load(open("%s/eval-%s-%s.json" % (out, level, s)))
        conv = [m for m in e["scores"] if m["model"] == "conventional"][0]
        cells.append(fmt(conv))
    print("| %s | " % level + " | ".join(cells) + " |")
EOF
