#!/usr/bin/env python3
"""Writes an RViz config (rviz/clod_haptics.rviz.in) whose camera frames a mesh, or runs RViz with it.

  make_rviz_config.py --bounds X0 Y0 Z0 X1 Y1 Z1 --out F.rviz [--frame world] [--marker]
                      [--focus X Y Z --zoom Z] [--yaw A --pitch A]
  make_rviz_config.py --run-rviz [--config auto|F.rviz] [--device marker] [--markers-topic /detector/markers]

The second form is the node clod_haptics.launch starts with rviz:=true: with --config auto it waits for the
detector's mesh marker (namespace "mesh"), takes the mesh's bounds and frame from it, writes
$ROS_HOME/clod_haptics_rviz/<frame>.rviz and runs RViz on it; with a file it runs RViz on that file at once.
The camera looks at the bounds' centre (or --focus) from a distance that shows the whole box (divided by --zoom);
the grid, the axes and the clip distance follow the model's size. --marker shows the stylus's interactive marker.
"""
import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import time

TEMPLATE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "rviz", "clod_haptics.rviz.in")
FIELD_OF_VIEW = 0.785  # rad, the template's vertical field of view


def nice_step(x):
    """The largest 1, 2 or 5 times a power of ten not above x (a grid cell size)."""
    p = 10.0 ** math.floor(math.log10(x))
    return max(m * p for m in (1.0, 2.0, 5.0) if m * p <= x)


def render(template, lo, hi, frame, marker, focus=None, zoom=1.0, yaw=0.8, pitch=0.55, cut=None):
    """The template's text with the camera, grid and axes fitted to the box [lo, hi]; cut (m): the near clip plane
    that far in front of the focal point, slicing the mesh there (a section through the contact)."""
    size = max(math.dist(lo, hi), 1e-6)
    centre = [(a + b) / 2.0 for a, b in zip(lo, hi)]
    focal = focus if focus is not None else centre
    distance = 0.85 * (size / 2.0) / math.tan(FIELD_OF_VIEW / 2.0) / zoom
    cell = nice_step(size / 6.0)
    values = {
        "FIXED_FRAME": frame,
        "FOCAL_X": focal[0], "FOCAL_Y": focal[1], "FOCAL_Z": focal[2],
        "DISTANCE": distance,
        "FOCAL_SHAPE": 0.02 * size / zoom,
        "NEAR_CLIP": distance - cut if cut is not None else max(1e-4, 0.002 * distance),
        "PITCH": pitch, "YAW": yaw,
        "CELL_SIZE": cell,
        "LINE_WIDTH": 0.005 * size,
        "GRID_Z": lo[2],
        "AXES_LENGTH": 0.1 * size,
        "AXES_RADIUS": 0.005 * size,
        "MARKER_ENABLED": "true" if marker else "false",
    }
    text = template
    for key, value in values.items():
        text = text.replace("@%s@" % key, "%.6g" % value if isinstance(value, float) else str(value))
    if "@" in text:
        raise ValueError("template placeholder left: " + text[text.index("@"):][:40])
    return text


def write(path, text):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def mesh_bounds_from_markers(topic, timeout):
    """(lo, hi, frame) of the first TRIANGLE_LIST marker in namespace "mesh" on topic, or None after timeout s."""
    import rospy
    from visualization_msgs.msg import Marker, MarkerArray

    found = []

    def on_markers(array):
        for m in array.markers:
            if m.ns == "mesh" and m.type == Marker.TRIANGLE_LIST and m.action == Marker.ADD and m.points and not found:
                xs = [p.x for p in m.points]
                ys = [p.y for p in m.points]
                zs = [p.z for p in m.points]
                found.append(([min(xs), min(ys), min(zs)], [max(xs), max(ys), max(zs)], m.header.frame_id))

    sub = rospy.Subscriber(topic, MarkerArray, on_markers, queue_size=2)
    deadline = time.monotonic() + timeout
    while not found and not rospy.is_shutdown() and time.monotonic() < deadline:
        time.sleep(0.1)
    sub.unregister()
    return found[0] if found else None


def run_rviz(args):
    import rospy

    rospy.init_node("rviz_config", disable_signals=True)
    config = args.config
    if config == "auto":
        rospy.loginfo("rviz_config: waiting for the mesh marker on %s", args.markers_topic)
        got = mesh_bounds_from_markers(args.markers_topic, args.timeout)
        if got is None:
            config = os.path.join(os.path.dirname(TEMPLATE), "clod_haptics.rviz")
            rospy.logwarn("rviz_config: no mesh marker on %s in %.0f s: RViz starts with %s",
                          args.markers_topic, args.timeout, config)
        else:
            lo, hi, frame = got
            home = os.environ.get("ROS_HOME", os.path.expanduser("~/.ros"))
            config = os.path.join(home, "clod_haptics_rviz", "%s.rviz" % (frame.strip("/").replace("/", "_") or "mesh"))
            with open(TEMPLATE) as f:
                write(config, render(f.read(), lo, hi, frame, args.device == "marker"))
            rospy.loginfo("rviz_config: mesh bounds %s to %s (frame %s): %s", lo, hi, frame, config)
    rviz = shutil.which("rviz") or "rviz"
    child = subprocess.Popen([rviz, "-d", config, "__name:=rviz"])
    stop = lambda *_: child.send_signal(signal.SIGINT)
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    code = child.wait()
    rospy.signal_shutdown("rviz exited")
    return code


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bounds", type=float, nargs=6, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"))
    ap.add_argument("--out", help="the .rviz file to write (with --bounds)")
    ap.add_argument("--frame", default="world", help="RViz's Fixed Frame: the mesh's frame")
    ap.add_argument("--marker", action="store_true", help="show the stylus's interactive marker")
    ap.add_argument("--focus", type=float, nargs=3, metavar=("X", "Y", "Z"), help="look here (default: the centre)")
    ap.add_argument("--zoom", type=float, default=1.0, help="camera distance divided by this")
    ap.add_argument("--yaw", type=float, default=0.8)
    ap.add_argument("--pitch", type=float, default=0.55)
    ap.add_argument("--template", default=TEMPLATE)
    ap.add_argument("--run-rviz", action="store_true", help="run RViz (a node of clod_haptics.launch)")
    ap.add_argument("--config", default="auto", help="with --run-rviz: auto or an .rviz file")
    ap.add_argument("--device", default="none", help="with --run-rviz: marker shows the stylus's marker")
    ap.add_argument("--markers-topic", default="/detector/markers")
    ap.add_argument("--timeout", type=float, default=120.0, help="s to wait for the mesh marker")
    args = ap.parse_args([a for a in sys.argv[1:] if ":=" not in a])  # roslaunch adds __name:= and __log:=
    if args.run_rviz:
        return run_rviz(args)
    if args.bounds is None or args.out is None:
        ap.error("--bounds and --out (or --run-rviz)")
    lo, hi = args.bounds[:3], args.bounds[3:]
    if any(h < l for l, h in zip(lo, hi)) or not all(math.isfinite(v) for v in args.bounds):
        ap.error("--bounds: finite X0 Y0 Z0 X1 Y1 Z1 with X0 <= X1, Y0 <= Y1, Z0 <= Z1")
    with open(args.template) as f:
        write(args.out, render(f.read(), lo, hi, args.frame, args.marker, args.focus, args.zoom, args.yaw, args.pitch))
    print("wrote %s" % args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
