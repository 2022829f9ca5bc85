#!/usr/bin/env bash
# Hardware-in-the-loop session on the real rig. Skips (exit 0) unless the three device
# variables are set:
#   RIGCAL_ARM_PORT    serial port of the Movemaster controller (e.g. /dev/ttyUSB0)
#   RIGCAL_TABLE_CAN   CAN interface of the table drives (e.g. can0 or slcan:/dev/ttyACM0)
#   RIGCAL_PANEL_PORT  serial port of the PenMount controller (e.g. /dev/ttyUSB1)
# Optional: RIGCAL_POINTS (default 20), RIGCAL_OUT (default hil-session-<date>).
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ -z "${RIGCAL_ARM_PORT:-}" || -z "${RIGCAL_TABLE_CAN:-}" || -z "${RIGCAL_PANEL_PORT:-}" ]]; then
    echo "hil-session: skipped: set RIGCAL_ARM_PORT, RIGCAL_TABLE_CAN and RIGCAL_PANEL_PORT to run on the rig"
    exit 0
fi

cat <<'CHECK'
Safety checklist — confirm every item before going on:
  [ ] Emergency stop within reach and tested; nobody inside the arm's or the table's reach.
  [ ] Table travel clear; the panel mounted on the z arm and its cable free to move.
  [ ] Pin fitted along tool x, tight; nothing on the panel.
  [ ] Arm at the nest (NT) or free to home; joint signs/offsets in the rig file measured.
  [ ] Drives powered, heartbeats visible on the CAN bus; the panel streaming on its port.
  [ ] Speeds in the rig file ([devices]) reviewed: arm `speed`, table profile velocity.
CHECK
read -r -p "Type 'yes' when every item is checked: " answer
[[ "$answer" == "yes" ]] || { echo "hil-session: aborted by the operator"; exit 1; }

rig=$(mktemp --suffix=.toml)
trap 'rm -f "$rig"' EXIT
# Replace the three `transport = "sim"` lines in [devices] order: arm, table, panel.
awk -v a="$RIGCAL_ARM_PORT" -v t="$RIGCAL_TABLE_CAN" -v p="$RIGCAL_PANEL_PORT" '
  /^\[devices\.arm\]/ {s="a"} /^\[devices\.table\]/ {s="t"} /^\[devices\.panel\]/ {s="p"}
  /^transport *=/ && s=="a" {print "transport = \"" a "\""; next}
  /^transport *=/ && s=="t" {print "transport = \"" t "\""; next}
  /^transport *=/ && s=="p" {print "transport = \"" p "\""; next}
  {print}' rigs/rv-m2.toml > "$rig"

out="${RIGCAL_OUT:-hil-session-$(date +%Y%m%d-%H%M%S)}"
cargo run --release -- session --rig "$rig" --out "$out" --points "${RIGCAL_POINTS:-20}" --registration-points 8
echo "hil-session: recording in $out (resume an interrupted run with: rigcal session --rig $rig --out $out --resume)"
