#!/usr/bin/env python3
"""Touches the mesh with the marker stylus (device:=marker) for a picture, then writes an RViz config that frames
the contact (scripts/screenshot.sh runs it).

Takes the mesh's bounds and its topmost vertex from the detector's mesh marker, sends the stylus (~goal of
marker_stylus) above that vertex, then straight down until the device point is --depth pointer radii deep (the
proxy stays on the surface beside it), stops there and writes --out: rviz/clod_haptics.rviz.in looking at the
contact from --zoom times closer than the whole-mesh view, its near clip plane cutting the mesh just in front of the
contact so the device point inside shows beside the proxy.
  screenshot_touch.py --out F.rviz [--out-full G.rviz] [--depth 1.5] [--zoom 4] [--timeout 90]
"""
import argparse
import math
import os
import sys
import time

import rospy
from clod_haptics.msg import Contact
from geometry_msgs.msg import PoseStamped

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_rviz_config  # noqa: E402


def goal(frame, x, y, z):
    g = PoseStamped()
    g.header.frame_id = frame
    g.pose.position.x, g.pose.position.y, g.pose.position.z = x, y, z
    g.pose.orientation.w = 1.0
    return g


def top_vertex(topic, timeout):
    """(lo, hi, frame, topmost vertex) of the detector's mesh marker."""
    from visualization_msgs.msg import Marker, MarkerArray

    found = []

    def on_markers(array):
        for m in array.markers:
            if m.ns == "mesh" and m.type == Marker.TRIANGLE_LIST and m.points and not found:
                pts = [(p.x, p.y, p.z) for p in m.points]
                lo = [min(c) for c in zip(*pts)]
                hi = [max(c) for c in zip(*pts)]
                found.append((lo, hi, m.header.frame_id, max(pts, key=lambda p: p[2])))

    sub = rospy.Subscriber(topic, MarkerArray, on_markers, queue_size=2)
    end = time.monotonic() + timeout
    while not found and time.monotonic() < end and not rospy.is_shutdown():
        time.sleep(0.1)
    sub.unregister()
    if not found:
        sys.exit("screenshot_touch: no mesh marker on %s in %.0f s" % (topic, timeout))
    return found[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="the close-up on the contact")
    ap.add_argument("--out-full", help="also the whole mesh as clod_haptics.launch frames it, the stylus marker shown")
    ap.add_argument("--depth", type=float, default=1.5, help="device point depth in pointer radii")
    ap.add_argument("--zoom", type=float, default=4.0)
    ap.add_argument("--timeout", type=float, default=90.0)
    args = ap.parse_args(rospy.myargv()[1:])
    rospy.init_node("screenshot_touch", anonymous=True)
    lo, hi, frame, top = top_vertex("/detector/markers", args.timeout)
    size = sum((b - a) ** 2 for a, b in zip(lo, hi)) ** 0.5
    pub = rospy.Publisher("/marker_stylus/goal", PoseStamped, queue_size=10, latch=True)
    last = {}
    sub = rospy.Subscriber("/detector/contact", Contact, lambda c: last.update(c=c), queue_size=100)
    # Above the topmost vertex, then down through it.
    pub.publish(goal(frame, top[0], top[1], hi[2] + 0.1 * size))
    end = time.monotonic() + args.timeout
    while time.monotonic() < end and not rospy.is_shutdown():
        c = last.get("c")
        if c and not c.in_contact and abs(c.pointer.z - (hi[2] + 0.1 * size)) < 1e-6:
            break
        time.sleep(0.05)
    pub.publish(goal(frame, top[0], top[1], lo[2]))
    while time.monotonic() < end and not rospy.is_shutdown():
        c = last.get("c")
        if c and c.in_contact and c.depth >= args.depth * c.pointer_radius:
            pub.publish(goal(frame, c.pointer.x, c.pointer.y, c.pointer.z))
            break
        time.sleep(0.0005)
    else:
        sys.exit("screenshot_touch: no contact under the topmost vertex")
    sub.unregister()
    time.sleep(1.0)
    c = last["c"]
    print("contact: depth %.4f m at (%.4f %.4f %.4f), proxy (%.4f %.4f %.4f), device point (%.4f %.4f %.4f)" % (
        c.depth, c.point.x, c.point.y, c.point.z, c.proxy.x, c.proxy.y, c.proxy.z,
        c.pointer.x, c.pointer.y, c.pointer.z))
    # Looking across the normal, so the normal, the proxy and the device point all lie in the picture's plane.
    n = c.normal
    yaw = math.atan2(n.y, n.x) + math.pi / 2 if math.hypot(n.x, n.y) > 1e-3 else 0.9
    with open(make_rviz_config.TEMPLATE) as f:
        text = make_rviz_config.render(f.read(), lo, hi, frame, False, focus=[c.point.x, c.point.y, c.point.z + 0.03 * size],
                                       zoom=args.zoom, yaw=yaw, pitch=0.08, cut=1.5 * c.pointer_radius)
    make_rviz_config.write(args.out, text)
    if args.out_full:
        with open(make_rviz_config.TEMPLATE) as f:
            make_rviz_config.write(args.out_full, make_rviz_config.render(f.read(), lo, hi, frame, True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
