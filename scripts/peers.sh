#!/usr/bin/env bash
# rigcal beside its Python peers, pybotics and FIGAROH, on the same recordings, in one run
# (issue 33's peer table; docs/benchmarks.md, Peers):
#   - rv-m2 structured: 2 200 simulated RV-M2 poses (seed 2024) of
#     benches/fixtures/structured-warm-up-rv-m2.toml: a first-harmonic gear error of 0.025° on
#     joints 1-3 and a 0.5 mm warm-up drift, no noise; what the geometry leaves is structure;
#   - ur10 A 1000: 1 000 rows of the UR10's Series A (../shared/data/ur10-landgraf, or UR10_DATA),
#     spread evenly over the series' 11 911 rows, positions only, imported as scripts/ur10.sh
#     imports it.
#
#     scripts/peers.sh
#
# Each tool fits the same rows of the same measurements.csv:
#   rigcal    `rigcal identify` (default level: analysis, fit, outlier search and judgement,
#             model file), PEERS_RUNS whole processes (default 11), the median printed;
#   pybotics  scripts/peer_pybotics.py (RV-M2) and scripts/peer_ur10.py (UR10): scipy's
#             least_squares on pybotics' position errors (`pip install pybotics`);
#   FIGAROH   scripts/peer_figaroh.py: its full_params calibration from a URDF and its YAML
#             configuration (`pip install figaroh`; the header of that script says more).
# The peers run once each (tens of seconds to minutes each). A peer that is not installed is
# skipped with a message. RIGCAL=path skips the build; PEERS="pybotics figaroh" picks the peers.
#
# The table: fit time (the peer's own least-squares or solve() call, timed inside its process;
# `rigcal identify` does not time its fit apart, see the identify benches for that), the whole
# process (wall and CPU = user + sys seconds), the 3-D position RMS after the fit on the fitted
# rows, and three ratios: the peer's whole process over rigcal's, in wall and in CPU seconds,
# and the peer's fit alone over rigcal's whole process (wall; a floor for fit against fit). The
# machine's load average is printed before and after: on a shared machine the CPU ratio is the
# steadier one.
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${PEERS_RUNS:-11}
PEERS=${PEERS:-pybotics figaroh}
UR10_DATA=${UR10_DATA:-../shared/data/ur10-landgraf}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

if [ -z "${RIGCAL:-}" ]; then
    cargo build --release --quiet --bin rigcal
    RIGCAL=target/release/rigcal
fi

have_peer() { # name -> 0 when installed, else a message and 1
    case "$1" in
    pybotics) python3 -c "import pybotics, scipy" 2>/dev/null && return 0
        echo "pybotics is not installed (pip install pybotics): skipped" >&2 ;;
    figaroh) python3 -c "import figaroh.calibration, pinocchio" 2>/dev/null && return 0
        echo "FIGAROH is not installed (pip install figaroh; see scripts/peer_figaroh.py): skipped" >&2 ;;
    *) echo "unknown peer $1 (pybotics, figaroh): skipped" >&2 ;;
    esac
    return 1
}

# timed OUT TIMES CMD... : runs CMD once, its output to OUT, "wall cpu" (s) to TIMES.
timed() {
    local out=$1 times=$2
    shift 2
    local TIMEFORMAT='%R %U %S'
    { time "$@" >"$out" 2>&1; } 2>"$WORK/time.raw"
    awk '{ printf "%.3f %.3f\n", $1, $2 + $3 }' "$WORK/time.raw" >"$times"
}

ratio() { awk -v p="$1" -v r="$2" 'BEGIN { printf "%.0f×", p / r }'; }
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

# --- the recordings --------------------------------------------------------------------------
RV=$WORK/rv-m2-structured
"$RIGCAL" simulate --rig rigs/rv-m2-ideal.toml --scenario benches/fixtures/structured-warm-up-rv-m2.toml \
    --random 2200 --seed 2024 --out "$RV" >/dev/null
RECORDINGS=(rv-m2)
if [ -f "$UR10_DATA/ur10.urdf" ]; then
    UR=$WORK/ur10-A1000
    "$RIGCAL" rig from-urdf "$UR10_DATA/ur10.urdf" --base base_link --tip tool0 --out "$WORK/ur10.toml" >/dev/null
    "$RIGCAL" import "$UR10_DATA/Series_A/measurements_grid.csv" --rig "$WORK/ur10.toml" \
        --joints shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint \
        --point measurement_x,measurement_y,measurement_z --length-unit mm --angle-unit rad \
        --out "$WORK/ur10-A" >/dev/null 2>&1
    mkdir -p "$UR"
    # Row r of n data rows is kept when floor(r·1000/n) steps: 1 000 rows spread over the series.
    awk -v keep=1000 -v n="$(($(wc -l <"$WORK/ur10-A/measurements.csv") - 1))" \
        'NR == 1 { print; next } { r = NR - 2; if (r == 0 || int(r * keep / n) != int((r - 1) * keep / n)) print }' \
        "$WORK/ur10-A/measurements.csv" >"$UR/measurements.csv"
    RECORDINGS+=(ur10)
else
    echo "no UR10 data at $UR10_DATA (set UR10_DATA): the UR10 rows are skipped" >&2
fi

display() { case "$1" in figaroh) echo FIGAROH ;; *) echo "$1" ;; esac; }
label() { case "$1" in rv-m2) echo "RV-M2 structured, 2 200 poses" ;; ur10) echo "UR10 Series A, 1 000 rows" ;; esac; }
rig_of() { case "$1" in rv-m2) echo rigs/rv-m2-ideal.toml ;; ur10) echo "$WORK/ur10.toml" ;; esac; }
rec_of() { case "$1" in rv-m2) echo "$RV" ;; ur10) echo "$UR" ;; esac; }

peer_cmd() { # peer recording -> the peer's command line
    case "$1:$2" in
    pybotics:rv-m2) echo python3 scripts/peer_pybotics.py "$RV/measurements.csv" ;;
    pybotics:ur10) echo python3 scripts/peer_ur10.py "$UR" ;;
    figaroh:rv-m2) echo python3 scripts/peer_figaroh.py "$RV" --rig rigs/rv-m2-ideal.toml ;;
    figaroh:ur10) echo python3 scripts/peer_figaroh.py "$UR" --urdf "$UR10_DATA/ur10.urdf" --base base_link --tip tool0 ;;
    esac
}

# The peer's own line: "RMS a -> b mm" and "fit c s".
peer_rms() { grep -o 'RMS [0-9.]* -> [0-9.]* mm' "$1" | tail -1 | awk '{ print $4 }'; }
peer_fit() { grep -o 'fit [0-9.]* s' "$1" | tail -1 | awk '{ print $2 }'; }

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
ROWS=()
for rec in "${RECORDINGS[@]}"; do
    # rigcal: RUNS whole processes after one warm-up run.
    "$RIGCAL" identify --rig "$(rig_of "$rec")" --recording "$(rec_of "$rec")" --out "$WORK/model.json" \
        >"$WORK/rigcal.txt" 2>&1
    : >"$WORK/rigcal.times"
    for _ in $(seq "$RUNS"); do
        timed "$WORK/rigcal.txt" "$WORK/t" "$RIGCAL" identify --rig "$(rig_of "$rec")" \
            --recording "$(rec_of "$rec")" --out "$WORK/model.json"
        cat "$WORK/t" >>"$WORK/rigcal.times"
    done
    r_wall=$(awk '{ print $1 }' "$WORK/rigcal.times" | median)
    r_cpu=$(awk '{ print $2 }' "$WORK/rigcal.times" | median)
    r_rms=$(awk '/residual after:/ { print $4 }' "$WORK/rigcal.txt")
    echo "== $(label "$rec"): rigcal identify, median of $RUNS: ${r_wall} s wall, ${r_cpu} s CPU, RMS after ${r_rms} mm"
    ROWS+=("$(label "$rec")|rigcal identify|—|$r_wall|$r_cpu|$r_rms|—|—|—")
    for peer in $PEERS; do
        have_peer "$peer" || continue
        # shellcheck disable=SC2046  # the command line is split into words on purpose
        timed "$WORK/$peer.txt" "$WORK/t" $(peer_cmd "$peer" "$rec") || true
        read -r p_wall p_cpu <"$WORK/t"
        p_rms=$(peer_rms "$WORK/$peer.txt")
        p_fit=$(peer_fit "$WORK/$peer.txt")
        if [ -z "$p_rms" ] || [ -z "$p_fit" ]; then
            echo "$peer failed on $rec; its output:" >&2
            tail -20 "$WORK/$peer.txt" >&2
            continue
        fi
        echo "== $(label "$rec"): $peer: $(grep -E 'RMS [0-9.]* ->' "$WORK/$peer.txt" | tail -1)"
        ROWS+=("$(label "$rec")|$(display "$peer")|$p_fit|$p_wall|$p_cpu|$p_rms|$(ratio "$p_wall" "$r_wall")|$(ratio "$p_cpu" "$r_cpu")|$(ratio "$p_fit" "$r_wall")")
    done
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| recording | tool | fit (s) | whole process, wall (s) | whole process, CPU (s) | RMS after (mm) | peer / rigcal, wall | peer / rigcal, CPU | peer's fit / rigcal's wall |"
echo "|---|---|---|---|---|---|---|---|---|"
for row in "${ROWS[@]}"; do
    echo "| ${row//|/ | } |"
done
