#!/bin/bash
# RViz under a virtual X server showing a mesh touched by the stylus, grabbed into a PNG:
#   scripts/screenshot.sh [OUT.png] [MESH] [SCALE]     (after sourcing the workspace's devel/setup.bash)
# MESH defaults to the bundled torus, SCALE to 1; SIZE=0.15 (environment) instead scales a .off or .obj mesh so
# its largest side is 0.15 m. The pipeline runs with device:=marker; scripts/screenshot_touch.py drives the stylus
# down onto the mesh's topmost vertex until the device point is 1.5 pointer radii deep (the proxy stays on the
# surface beside it) and writes an RViz config framing the contact; RViz then starts on it and the screen is
# grabbed (ImageMagick's import). Its own ROS master on a free port, so a running roscore is left alone.
# POINTER_RADIUS (m) and LAUNCH_ARGS (more clod_haptics.launch arguments) are passed on.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
OUT=$(realpath -m "${1:-.build/screenshot.png}")
MESH=$(realpath -m "${2:-$HERE/../data/meshes/torus.obj}")
SCALE=${3:-1.0}
if [ -n "${SIZE:-}" ]; then
  SCALE=$(python3 - "$MESH" "$SIZE" <<'PY'
import sys
path, size = sys.argv[1], float(sys.argv[2])
with open(path) as f:
    if path.lower().endswith(".off"):
        words = f.read().split()
        words = words[1:] if words[0].upper().endswith("OFF") else words
        n = int(words[0])
        v = [[float(x) for x in words[3 + 3 * k:6 + 3 * k]] for k in range(n)]
    else:
        v = [[float(x) for x in l.split()[1:4]] for l in f if l.startswith("v ")]
print(size / max(max(c) - min(c) for c in zip(*v)))
PY
)
fi
mkdir -p "$(dirname "$OUT")"
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("localhost", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://localhost:$PORT
CONFIG=$(mktemp -d)/view.rviz   # the RViz configs screenshot_touch.py writes
echo "screenshot: $MESH at scale $SCALE -> $OUT (log: $OUT.log)"

/usr/bin/xvfb-run -a -s "-screen 0 1280x800x24" bash -c '
  set -u
  roslaunch -p '"$PORT"' clod_haptics clod_haptics.launch device:=marker rviz:=false mesh:="'"$MESH"'" \
    scale:='"$SCALE"' pointer_radius:='"${POINTER_RADIUS:-0.002}"' '"${LAUNCH_ARGS:-}"' > "'"$OUT"'.log" 2>&1 &
  launch=$!
  rosrun clod_haptics static_frame _parent:=world _child:=world_clod_mesh __name:=mesh_frame >> "'"$OUT"'.log" 2>&1 &
  frame=$!
  status=0
  python3 '"$HERE"'/screenshot_touch.py --out "'"$CONFIG"'" --out-full "'"${CONFIG%.rviz}_full.rviz"'" && {
    for view in full close; do
      cfg="'"$CONFIG"'"; [ $view = full ] && cfg="'"${CONFIG%.rviz}_full.rviz"'"
      rviz -d "$cfg" >> "'"$OUT"'.log" 2>&1 &
      rviz=$!
      sleep 15   # RViz (software rendering) starts, gets the markers and draws a few frames
      /usr/bin/import -window root "'"$OUT"'.$view.png"
      kill -TERM $rviz 2>/dev/null || true
      wait $rviz 2>/dev/null || true
    done
    # Side by side: RViz as the launch file frames the mesh, and the 3D view of the close-up (cropped, same height);
    # a legend under them.
    /usr/bin/convert "'"$OUT"'.close.png" -crop 900x708+364+62 +repage -resize x800 "'"$OUT"'.close.png"
    /usr/bin/convert "'"$OUT"'.full.png" "'"$OUT"'.close.png" +append "'"$OUT"'"
    /usr/bin/convert "'"$OUT"'" -background "#202020" -fill white -font DejaVu-Sans -pointsize 22 \
      -size "$(/usr/bin/identify -format %w "'"$OUT"'")x" \
      caption:"'"$(basename "$MESH") at scale $SCALE"'. Left: RViz framed on the mesh (clod_haptics.launch rviz:=true device:=marker; the ball and arrows drag the stylus). Right: the contact, the view cutting the mesh there: blue proxy on the surface, red device point sunk in, magenta contact point, yellow normal, green force." \
      -gravity center -append "'"$OUT"'"
    rm -f "'"$OUT"'.full.png" "'"$OUT"'.close.png"
  } || status=1
  kill -TERM $frame $launch 2>/dev/null || true  # background jobs of a script ignore SIGINT
  wait $launch 2>/dev/null || true
  exit $status
'
echo "screenshot: $OUT"
