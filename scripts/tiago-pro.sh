#!/usr/bin/env bash
# Real data end to end: the TIAGo Pro's three motion-capture sessions (tests/data/tiago-pro/,
# provenance there) through `rig from-urdf`, `import`, `identify` and `diagnose`, printing the
# figures of the README's TIAGo Pro table. The sessions are not registered to each other (the
# mocap frame moved between days): held-out figures keep the kinematic parameters and refit the
# measurement frame on each held-out session. Usage: scripts/tiago-pro.sh [OUT] (default out/tiago-pro).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/tiago-pro}
DATA=tests/data/tiago-pro
mkdir -p "$OUT"
cargo build --release --quiet
R=target/release/rigcal
JOINTS=torso_lift_joint,arm_right_1_joint,arm_right_2_joint,arm_right_3_joint,arm_right_4_joint,arm_right_5_joint,arm_right_6_joint,arm_right_7_joint

echo "== rig from the URDF (kept as rigs/tiago-pro.toml)"
$R rig from-urdf $DATA/tiago_pro_local.urdf --base base_footprint --tip gripper_right_pal_atc_base_link --out "$OUT/tiago-pro.toml"
RIG=rigs/tiago-pro.toml

echo "== import (metres and radians, no time column)"
for s in 0701_0913 0702_0756 0805_1246; do
  $R import $DATA/calibration_samples_2026$s.csv --rig $RIG --joints $JOINTS --point x1,y1,z1 --out "$OUT/${s:0:4}"
done

held_of() { # the sessions not in the training set
  for d in 0701 0702 0805; do [[ " $* " == *" $d "* ]] || printf '%s ' "$OUT/$d"; done
}

for train in "0701" "0702" "0805" "0701 0702" "0701 0805" "0702 0805"; do
  set -- $train
  with=()
  [[ $# -gt 1 ]] && with=(--with-session "$OUT/$2")
  for level in frames offsets full; do
    echo "== identify, train $train, level $level"
    # shellcheck disable=SC2046
    $R identify --rig $RIG --recording "$OUT/$1" "${with[@]}" --level $level \
      --heldout-session $(held_of "$@") --out "$OUT/model-${train// /+}-$level.json" \
      | grep -E "^(training|held-out|outlier)"
  done
done

for train in 0701 0702 0805; do
  echo "== diagnose $train, held-out sessions with the frame refitted"
  # shellcheck disable=SC2046
  $R diagnose --rig $RIG --recording "$OUT/$train" --heldout-session $(held_of $train) \
    --json "$OUT/diagnosis-$train.json" | grep -E "^(effect|  deg_per_nm|unexplained|outlier|RMS|held-out|  training|  held-out)"
done
