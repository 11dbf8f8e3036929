#!/bin/bash
# The force loop's latency end to end in the shipped launch/clod_haptics.launch (device:=phantom, the bridge and
# the detector nodelet in its manager), on the fake libHD: from the servo callback reading a pose to the servo
# callback getting the force that answers it (pose -> bridge thread -> /phantom/pose -> detector ->
# /phantom/force_feedback -> bridge thread -> servo callback). The bridge prints the percentiles when it stops.
#   bash scripts/force_loop_latency.sh [seconds (default 30)] [roslaunch args]
# after sourcing the workspace's devel/setup.bash (phantom_bridge_fake_hd is a build-tree binary). The fake
# stylus goes down into the top of the bundled torus and back every 2 s, from 8 mm above it to 3 mm into it, so
# the proxy slides and holds the surface half of the time. With servo rendering (the default: the bridge runs
# the proxy in the servo callback) the loop closes within a servo frame; servo_render:=false (passed to the
# bridge as a roslaunch argument of device_phantom.launch, or set CLOD_SERVO_RENDER=false) measures the ROS round
# trip instead. Own ROS master on a free port.
# A benchmark: it prints figures and never fails on them.
set -euo pipefail
SECONDS_TO_RUN=${1:-30}
shift || true
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("localhost", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://localhost:$PORT
export CLOD_PHANTOM_BRIDGE_TYPE=phantom_bridge_fake_hd CLOD_PHANTOM_BACKEND=openhaptics
export CLOD_FAKE_HD_PATH=60,30,0,60,19,0,2  # device mm (x, y up, z): ROS (0.060, 0, 0.030) to 3 mm under the top
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
