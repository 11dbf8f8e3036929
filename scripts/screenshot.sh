#!/bin/bash
# Starts the whole pipeline with RViz under a virtual X server, holds a stylus pose that touches the
# bundled torus (published on /phantom/pose), and grabs the screen into a PNG.
#   scripts/screenshot.sh [OUT.png]     (after sourcing the workspace's devel/setup.bash)
# Uses its own ROS master on a free port, so a running roscore is left alone.
set -euo pipefail
OUT=$(realpath -m "${1:-.build/screenshot.png}")
mkdir -p "$(dirname "$OUT")"
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("localhost", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://localhost:$PORT
# A point 1 mm outside the torus's outer equator: with the 2 mm pointer, a 1 mm deep contact.
POSE='{header: {frame_id: world}, pose: {position: {x: 0.083, y: 0.0, z: 0.004}, orientation: {w: 1.0}}}'

/usr/bin/xvfb-run -a -s "-screen 0 1280x800x24" bash -c '
  set -u
  roslaunch -p '"$PORT"' clod_haptics clod_haptics.launch rviz:=true > "'"$OUT"'.log" 2>&1 &
  launch=$!
  for i in $(seq 1 60); do
    rostopic echo -n 1 /detector/status 2>/dev/null | grep -q "level_spheres: [1-9]" && break
    sleep 1
  done
  rostopic pub -r 50 /phantom/pose geometry_msgs/PoseStamped "'"$POSE"'" > /dev/null 2>&1 &
  pub=$!
  sleep 12   # RViz (software rendering) starts, gets the markers and draws a few frames
  rostopic echo -n 1 /detector/contact | grep -E "in_contact|depth" || true
  /usr/bin/import -window root "'"$OUT"'"
  kill $pub 2>/dev/null || true
  kill -INT $launch 2>/dev/null || true
  wait $launch 2>/dev/null || true
'
echo "screenshot: $OUT"
