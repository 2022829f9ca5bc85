#!/usr/bin/env bash
# The peer of the UR10 table: pybotics' least-squares calibration (scripts/peer_ur10.py) on a
# training recording, scored on held-out recordings with only their world (tracker) frame
# refitted, as `rigcal evaluate --refit-frame` scores rigcal's models.
#
# Install the peer once (Python 3.8+; pybotics pulls numpy, scipy and attrs):
#     pip install pybotics          # tested with pybotics 3.1.2, numpy 2.x, scipy 1.x
# Then:
#     scripts/peer_ur10.sh TRAIN_DIR HELD_DIR... [--every N]
# with recordings `rigcal import` wrote (scripts/ur10.sh makes them). pybotics computes each
# pose's kinematics in Python: ~2 000 training poses take about 3 min of CPU, so scripts/ur10.sh
# gives it a spread subset of Series A (every N-th row) and scores rigcal on the same subset.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -c "import pybotics, scipy" 2>/dev/null || {
    echo "pybotics (with numpy and scipy) is not installed: pip install pybotics" >&2
    exit 1
}
exec python3 scripts/peer_ur10.py "$@"
