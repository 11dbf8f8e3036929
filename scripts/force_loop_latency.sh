#!/bin/bash
# The force loop's latency end to end in the shipped launch/clod_haptics.launch (device:=phantom, the bridge and
# the detector nodelet in its manager), on the fake libHD: from the servo callback reading a pose to the servo
# callback getting the force that answers it (pose -> bridge thread -> /phantom/pose -> detector ->
# /phantom/force_feedback -> bridge thread -> servo callback). The bridge prints the percentiles when it stops.
#   bash scripts/force_loop_latency.sh [seconds (default 30)] [roslaunch args]
# after sourcing the workspace's devel/setup.bash (phantom_bridge_fake_hd is a build-tree binary). The fake
# stylus rests 1 mm inside the bundled torus, so every pose is in contact. Own ROS master on a free port.
# A benchmark: it prints figures and never fails on them.
set -euo pipefail
SECONDS_TO_RUN=${1:-30}
shift || true
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("localhost", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://localhost:$PORT
export CLOD_PHANTOM_BRIDGE_TYPE=phantom_bridge_fake_hd CLOD_PHANTOM_BACKEND=openhaptics
export CLOD_FAKE_HD_POSITION=60,21,0  # device mm: ROS (0.060, 0, 0.021), 1 mm under the torus' top
LOG=$(mktemp /tmp/clod_force_loop.XXXXXX.log)
roslaunch -p "$PORT" clod_haptics clod_haptics.launch device:=phantom "$@" > "$LOG" 2>&1 &
LAUNCH=$!
sleep "$SECONDS_TO_RUN"
kill -INT "$LAUNCH"
wait "$LAUNCH" || true
if grep -q "force loop" "$LOG"; then
  grep -o "phantom_bridge: [0-9]* ticks.*" "$LOG" | sed 's/; /\n  /g'
  grep -m1 "pose_path\|poses" "$LOG" || true
else
  tail -30 "$LOG"
  echo "the bridge did not report a force loop (log: $LOG)"
  exit 1
fi
rm -f "$LOG"
