#!/usr/bin/env bash
# Hardware-in-the-loop session on the real rig, or its rehearsal through the same transports.
#
# On the rig: skips (exit 0) unless the three device variables are set:
#   RIGCAL_ARM_PORT    serial port of the Movemaster controller (e.g. /dev/ttyUSB0)
#   RIGCAL_TABLE_CAN   CAN interface of the table drives (e.g. can0 or slcan:/dev/ttyACM0)
#   RIGCAL_PANEL_PORT  serial port of the PenMount controller (e.g. /dev/ttyUSB1)
#
# Rehearsal (`scripts/hil-session.sh --rehearsal`, no hardware): `rigcal sim-device rig --pty`
# serves the rig's three emulators on pseudo-terminals around one simulated world (the
# scenario's, as in `rigcal session --sim`), and the same session runs through the serial and
# slcan code paths; its points and readings are the dry run's (docs/sessions.md, Rehearsal).
#   RIGCAL_RIG   rig file (default rigs/rv-m2.toml; its speeds are the rig's: ~3.5 s a point)
#   RIGCAL_SIM   scenario (default sim/rig-realistic.toml)
#
# Both: RIGCAL_POINTS (default 20), RIGCAL_OUT (default hil-session-<date>), RIGCAL_SEED (the
# plan's and registration's seed, default 1), RIGCAL_BIN (the rigcal binary; default
# `cargo run --release --`).
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ -n "${RIGCAL_BIN:-}" ]]; then
    rigcal=("$RIGCAL_BIN")
else
    rigcal=(cargo run --release --quiet --)
fi
out="${RIGCAL_OUT:-hil-session-$(date +%Y%m%d-%H%M%S)}"
seed="${RIGCAL_SEED:-1}"

# The session, the same on the rig and in the rehearsal: only the rig file differs.
run_session() {
    "${rigcal[@]}" session --rig "$1" --out "$out" --points "${RIGCAL_POINTS:-20}" \
        --registration-points 8 --seed "$seed"
    echo "hil-session: recording in $out (resume an interrupted run with: rigcal session --rig $1 --out $out --resume --seed $seed)"
}

if [[ "${1:-}" == "--rehearsal" ]]; then
    tmp=$(mktemp -d)
    server=""
    # SIGTERM: the server closes its ports and removes its socket; wait for it to have done so.
    trap '[[ -n "$server" ]] && kill "$server" 2>/dev/null && wait "$server"; rm -rf "$tmp"' EXIT
    base="${RIGCAL_RIG:-rigs/rv-m2.toml}"
    sim="${RIGCAL_SIM:-sim/rig-realistic.toml}"
    "${rigcal[@]}" sim-device rig --rig "$base" --sim "$sim" --pty --write-rig "$tmp/rig.toml" \
        > "$tmp/ports" &
    server=$!
    for _ in $(seq 100); do
        [[ -f "$tmp/rig.toml" ]] && break
        kill -0 "$server" 2>/dev/null || { echo "hil-session: the emulators' server stopped"; exit 1; }
        sleep 0.1
    done
    [[ -f "$tmp/rig.toml" ]] || { echo "hil-session: no rig file from the emulators' server within 10 s"; exit 1; }
    echo "hil-session: rehearsal on $(tr '\n' ' ' < "$tmp/ports")"
    run_session "$tmp/rig.toml"
    echo "hil-session: the dry run to compare with: rigcal session --rig $base --sim $sim --out DIR --points ${RIGCAL_POINTS:-20} --registration-points 8 --seed $seed"
    exit 0
fi

if [[ -z "${RIGCAL_ARM_PORT:-}" || -z "${RIGCAL_TABLE_CAN:-}" || -z "${RIGCAL_PANEL_PORT:-}" ]]; then
    echo "hil-session: skipped: set RIGCAL_ARM_PORT, RIGCAL_TABLE_CAN and RIGCAL_PANEL_PORT to run on the rig (or rehearse: $0 --rehearsal)"
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

run_session "$rig"
