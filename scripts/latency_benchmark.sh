#!/bin/bash
# Pose-to-contact latency of the detector as clod_haptics.launch runs it (its defaults): 1 kHz poses from another process
# for 60 s on mannequin-devil.off (scaled to 20 cm) with the markers subscribed out of process.
#   scripts/latency_benchmark.sh [roslaunch args, e.g. duration:=60 mesh:=... scale:=...]
# after sourcing the workspace's devel/setup.bash. Uses its own ROS master on a free port.
# A benchmark: it prints figures (median, p99, unanswered) and never fails on them.
set -euo pipefail
HERE=$(cd "$(dirname "$0")/.." && pwd)
SHARED=${CLOD_SHARED_DIR:-$(realpath -m "$HERE/../shared")}
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("localhost", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://localhost:$PORT
LOG=$(mktemp /tmp/clod_latency.XXXXXX.log)
roslaunch -p "$PORT" clod_haptics latency_benchmark.launch mesh:="$SHARED/data/meshes/mannequin-devil.off" "$@" \
  > "$LOG" 2>&1 || true
if grep -q "== latency_benchmark" "$LOG"; then
  sed -n '/== latency_benchmark/,/targets:/p' "$LOG"
else
  tail -30 "$LOG"
  echo "latency benchmark did not report (log: $LOG)"
  exit 1
fi
rm -f "$LOG"
