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
#
# The variable D-H model (`calibrate --recording`) is trained on the same rows twice: with seed
# 000's settings (every basis parameter per region, 110 regions, FCMAC trained on the CEPs and
# then the points), and with the settings chosen on Series A alone (an internal split: even
# grid positions against odd ones; docs/real-data.md): only the base's and the positioning
# joints' parameters per region, 4 regions, FCMAC trained on the CEPs.
#
# The peer: pybotics (scripts/peer_ur10.sh; `pip install pybotics`) on every UR10_PEER_EVERY-th
# row of A (default 6: pybotics computes each pose in Python, ~3 min for ~2 000 poses), with
# rigcal's conventional fit on the same rows beside it. UR10_PEER=0 skips it.
# UR10_LEVELS (default "frames offsets full") picks the `identify` levels; frames and offsets
# take most of the run (their outlier judgement on 11 911 rows).
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

levels="${UR10_LEVELS:-frames offsets full}"
evaluate() { # model-name
  for s in B C D; do
    "$rigcal" evaluate --model "$out/model-$1.json" --recording "$out/rec-$s" --refit-frame \
      --json "$out/eval-$1-$s.json" > "$out/eval-$1-$s.txt"
  done
}
for level in $levels; do
  echo "== identify on $(basename "$train") at level $level"
  "$rigcal" identify --rig "$out/ur10.toml" --recording "$train" --level "$level" \
    --out "$out/model-$level.json" | grep -v '^outlier removed' || true
  evaluate "$level"
done

echo "== calibrate (variable D-H model) on $(basename "$train"), seed 000's settings"
"$rigcal" calibrate --rig "$out/ur10.toml" --recording "$train" \
  --out "$out/model-variable-paper.json" > "$out/calibrate-paper.txt"
evaluate variable-paper
echo "== calibrate (variable D-H model) on $(basename "$train"), settings chosen on Series A"
"$rigcal" calibrate --rig "$out/ur10.toml" --recording "$train" --region-params positioning \
  --max-regions 4 --fcmac-training ceps --out "$out/model-variable.json" > "$out/calibrate.txt"
evaluate variable

peer_every="${UR10_PEER_EVERY:-6}"
if [ "${UR10_PEER:-1}" != 0 ]; then
  # Every N-th data row of A for the peer, and rigcal's conventional fit on the same rows
  # (the division's root fit, no outlier removal: pybotics removes none either).
  rm -rf "$out/rec-A-peer" && mkdir -p "$out/rec-A-peer"
  cp "$out/rec-A/session.toml" "$out/rec-A-peer/"
  awk -v n="$peer_every" 'NR == 1 || (NR - 2) % n == 0' "$out/rec-A/measurements.csv" \
    > "$out/rec-A-peer/measurements.csv"
  echo "== rigcal's conventional fit on every ${peer_every}th row of A (the peer's split)"
  "$rigcal" calibrate --rig "$out/ur10.toml" --recording "$out/rec-A-peer" --max-regions 1 \
    --fcmac-training ceps --out "$out/model-peer-split.json" > /dev/null
  evaluate peer-split
  echo "== pybotics on the same rows (scripts/peer_ur10.sh; minutes)"
  if ! "$here/scripts/peer_ur10.sh" "$out/rec-A-peer" "$out/rec-B" "$out/rec-C" "$out/rec-D" \
    > "$out/peer.txt"; then
    echo "the peer did not run (pip install pybotics); its row is left out" >&2
    rm -f "$out/peer.txt"
  fi
fi

echo
echo "UR10, trained on $(basename "$train"), held out with the measurement frame refitted per series"
echo "position error mm (mean / RMS / max), orientation error deg (RMS)"
python3 - "$out" "$levels" <<'EOF'
import json, os, re, sys
out, levels = sys.argv[1], sys.argv[2].split()
def fmt(s):
    p = s["position"]; o = s.get("orientation")
    return "%.3f / %.3f / %.3f" % (p["mean_mm"], p["rms_mm"], p["max_mm"]) + \
        (", %.3f°" % o["rms_deg"] if o else "")
def row(label, model, name=None, index=None):
    cells = []
    for s in "BCD":
        sc = json.load(open("%s/eval-%s-%s.json" % (out, model, s)))["scores"]
        m = sc[index] if index is not None else [m for m in sc if m["model"] == name][0]
        cells.append(fmt(m))
    print("| %s | " % label + " | ".join(cells) + " |")
print("| level | " + " | ".join("Series %s" % s for s in "BCD") + " |")
print("|---|---|---|---|")
row("nominal, frame refitted", "variable", index=0)
row("nominal, frame + marker refitted (in sample)", "variable", index=1)
for level in levels:
    row("%s (identify)" % level, level, "conventional")
row("seed 000's settings: conventional fit of the same file", "variable-paper", "conventional")
row("seed 000's settings: + regions (110)", "variable-paper", "regions")
row("seed 000's settings: + FCMAC", "variable-paper", "fcmac")
row("chosen on A: + regions (4, positioning joints)", "variable", "regions")
row("chosen on A: + FCMAC", "variable", "fcmac")
if os.path.exists("%s/eval-peer-split-B.json" % out):
    row("peer split: rigcal full geometric (no outlier removal)", "peer-split", "conventional")
if os.path.exists("%s/peer.txt" % out):
    cells = {}
    for line in open("%s/peer.txt" % out):
        m = re.search(r"rec-([BCD]) .*mean ([0-9.]+) / RMS ([0-9.]+) / max ([0-9.]+) mm", line)
        if m:
            cells[m.group(1)] = "%s / %s / %s" % m.group(2, 3, 4)
            o = re.search(r"orientation mean [0-9.]+ / RMS ([0-9.]+)", line)
            if o:
                cells[m.group(1)] += ", %s°" % o.group(1)
    print("| peer split: pybotics (25 MDH parameters) | " + " | ".join(cells.get(s, "-") for s in "BCD") + " |")
EOF
