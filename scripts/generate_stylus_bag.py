#!/usr/bin/env python3
"""Writes a bag of synthetic stylus motion over a mesh, at a haptic rate (1 kHz by default).

The stylus approaches the surface along its normal, presses into it, slides along it (staying
pressed in by --depth, following the surface), then retracts: the motion a user makes when
touching a model, so a detector driven by it sees free space, the first contact, a sustained
sliding contact and the release. Messages are geometry_msgs/PoseStamped in metres on
/phantom/pose (the Phantom drivers' topic), the format bag_replay reads.

Usage:
  generate_stylus_bag.py --mesh data/meshes/torus.obj --out data/bags/torus_stylus.bag
The mesh (OBJ or OFF) is read here, no dependency beyond python3-rosbag. The contact point is
the top of the mesh (highest upward-facing triangle) unless --start gives a point to project;
the slide goes around the vertical axis through the mesh centre unless --direction is given.
"""
import argparse
import math
import sys

import rosbag
import rospy
from geometry_msgs.msg import PoseStamped


# ----------------------------------------------------------------------------- small vector maths
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    return math.sqrt(dot(a, a))


def unit(a):
    n = norm(a)
    return mul(a, 1.0 / n) if n > 0 else (0.0, 0.0, 0.0)


def lerp(a, b, u):
    return add(a, mul(sub(b, a), u))


def smoothstep(u):
    u = min(1.0, max(0.0, u))
    return u * u * (3 - 2 * u)


# ----------------------------------------------------------------------------- mesh
def read_mesh(path, scale):
    """Vertices and triangles (polygons fanned) of an OBJ or OFF file."""
    verts, tris = [], []
    with open(path) as f:
        text = f.read()
    if path.lower().endswith(".off"):
        tokens = []
        for line in text.splitlines():
            line = line.split("#")[0].strip()
            if line:
                tokens.append(line)
        header = tokens[0]
        if not header.startswith("OFF"):
            raise ValueError("%s: not an OFF file" % path)
        rest = header[3:].split()
        counts_line = 1
        if not rest:
            rest = tokens[1].split()
            counts_line = 2
        nv, nf = int(rest[0]), int(rest[1])
        for line in tokens[counts_line:counts_line + nv]:
            x, y, z = map(float, line.split()[:3])
            verts.append((x * scale, y * scale, z * scale))
        for line in tokens[counts_line + nv:counts_line + nv + nf]:
            fields = list(map(int, line.split()))
            idx = fields[1:1 + fields[0]]
            for k in range(1, len(idx) - 1):
                tris.append((idx[0], idx[k], idx[k + 1]))
    else:
        for line in text.splitlines():
            fields = line.split()
            if not fields:
                continue
            if fields[0] == "v":
                verts.append(tuple(float(v) * scale for v in fields[1:4]))
            elif fields[0] == "f":
                idx = []
                for field in fields[1:]:
                    i = int(field.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                for k in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[k], idx[k + 1]))
    if not tris:
        raise ValueError("%s: no triangles" % path)
    return verts, tris


def closest_on_triangle(p, a, b, c):
    """Closest point to p on triangle abc (Ericson, Real-Time Collision Detection 5.1.5)."""
    ab, ac, ap = sub(b, a), sub(c, a), sub(p, a)
    d1, d2 = dot(ab, ap), dot(ac, ap)
    if d1 <= 0 and d2 <= 0:
        return a
    bp = sub(p, b)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    if d3 >= 0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return add(a, mul(ab, d1 / (d1 - d3)))
    cp = sub(p, c)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    if d6 >= 0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return add(a, mul(ac, d2 / (d2 - d6)))
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return add(b, mul(sub(c, b), w))
    denom = 1.0 / (va + vb + vc)
    return add(a, add(mul(ab, vb * denom), mul(ac, vc * denom)))


class Surface:
    def __init__(self, verts, tris):
        # Inside-out files (negative signed volume) are flipped, as the core's loader does, so
        # normals point out and "press in" means into the solid.
        volume = sum(dot(verts[a], cross(verts[b], verts[c])) for a, b, c in tris) / 6.0
        if volume < 0:
            tris = [(a, c, b) for a, b, c in tris]
        self.verts, self.tris = verts, tris
        self.normals = [unit(cross(sub(verts[b], verts[a]), sub(verts[c], verts[a]))) for a, b, c in tris]
        self.centroids = [mul(add(add(verts[a], verts[b]), verts[c]), 1.0 / 3) for a, b, c in tris]
        self.radii = [max(norm(sub(verts[i], cen)) for i in t) for t, cen in zip(tris, self.centroids)]
        lo = [min(v[k] for v in verts) for k in range(3)]
        hi = [max(v[k] for v in verts) for k in range(3)]
        self.centre = tuple((lo[k] + hi[k]) / 2 for k in range(3))
        self.size = max(hi[k] - lo[k] for k in range(3))

    def closest(self, p, search=None):
        """(point, triangle index) closest to p; search bounds the distance looked at, if given."""
        best, best_d, best_t = None, float("inf"), -1
        for t, (a, b, c) in enumerate(self.tris):
            if search is not None and norm(sub(self.centroids[t], p)) - self.radii[t] > search:
                continue
            q = closest_on_triangle(p, self.verts[a], self.verts[b], self.verts[c])
            d = norm(sub(q, p))
            if d < best_d:
                best, best_d, best_t = q, d, t
        if best is None:
            return self.closest(p)
        return best, best_t

    def top(self):
        """Centroid of the highest triangle facing up."""
        candidates = [t for t, n in enumerate(self.normals) if n[2] > 0.9] or range(len(self.tris))
        t = max(candidates, key=lambda i: self.centroids[i][2])
        return self.centroids[t], t


# ----------------------------------------------------------------------------- motion
def slide_keyframes(surface, start, tri, direction, length, steps, depth):
    """Pressed-in points following the surface from start over length, steps + 1 of them."""
    step = length / steps
    c, t = start, tri
    n = surface.normals[t]
    d = direction(c)
    points = []
    for _ in range(steps + 1):
        points.append(sub(c, mul(n, depth)))
        tangent = unit(sub(d, mul(n, dot(d, n))))
        if norm(tangent) == 0:
            tangent = unit(cross(n, (1.0, 0.0, 0.0))) or unit(cross(n, (0.0, 1.0, 0.0)))
        guess = add(add(c, mul(tangent, step)), mul(n, 0.25 * step))
        c, t = surface.closest(guess, search=4 * step + 0.002)
        n_new = surface.normals[t]
        if dot(n_new, n) > -0.5:  # ignore a jump to a face pointing the other way
            n = unit(add(n, n_new)) if norm(add(n, n_new)) > 0 else n_new
        d = direction(c) if direction is not None else tangent
        if dot(d, tangent) < 0:
            d = tangent
    return points


def build_motion(surface, args):
    if args.start:
        c0, t0 = surface.closest(tuple(args.start))
    else:
        c0, t0 = surface.top()
    n0 = surface.normals[t0]
    if args.direction:
        fixed = unit(tuple(args.direction))
        direction = lambda c: fixed  # noqa: E731
    else:
        # Around the vertical axis through the mesh centre (along a torus' ring, around a head).
        axis = (0.0, 0.0, 1.0)
        direction = lambda c: unit(cross(axis, sub(c, surface.centre))) if norm(  # noqa: E731
            cross(axis, sub(c, surface.centre))) > 1e-9 else (1.0, 0.0, 0.0)
    steps = max(2, int(round(args.slide * args.keyframe_rate)))
    slide = slide_keyframes(surface, c0, t0, direction, args.slide_length, steps, args.depth)
    c_end, t_end = surface.closest(add(slide[-1], mul(surface.normals[t0], args.depth)), search=0.01)
    n_end = surface.normals[t_end]

    above = add(c0, mul(n0, args.height))
    touch = c0
    pressed = sub(c0, mul(n0, args.depth))
    lifted = add(c_end, mul(n_end, args.height))

    segments = []  # (duration, function of u in [0, 1] -> position)
    segments.append((args.approach, lambda u: lerp(above, touch, smoothstep(u))))
    segments.append((args.press, lambda u: lerp(touch, pressed, smoothstep(u))))

    def along(u):
        x = smoothstep(u) * (len(slide) - 1)
        i = min(int(x), len(slide) - 2)
        return lerp(slide[i], slide[i + 1], x - i)

    segments.append((args.slide, along))
    segments.append((args.retract, lambda u: lerp(slide[-1], lifted, smoothstep(u))))

    total = sum(d for d, _ in segments)
    count = int(math.floor(total * args.rate + 1e-9)) + 1
    positions = []
    for k in range(count):
        t = k / args.rate
        for duration, f in segments:
            if t <= duration or f is segments[-1][1]:
                positions.append(f(min(1.0, t / duration) if duration > 0 else 1.0))
                break
            t -= duration
    phases = [(d, name) for (d, _), name in zip(segments, ("approach", "press", "slide", "retract"))]
    return positions, phases, c0, n0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mesh", required=True, help="OBJ or OFF mesh, in metres after --scale")
    parser.add_argument("--out", required=True, help="bag to write")
    parser.add_argument("--scale", type=float, default=1.0, help="factor from the mesh file's unit to metres")
    parser.add_argument("--rate", type=float, default=1000.0, help="pose rate, Hz")
    parser.add_argument("--topic", default="/phantom/pose")
    parser.add_argument("--frame", default="world")
    parser.add_argument("--approach", type=float, default=1.5, help="seconds")
    parser.add_argument("--press", type=float, default=0.75, help="seconds")
    parser.add_argument("--slide", type=float, default=4.0, help="seconds")
    parser.add_argument("--retract", type=float, default=1.25, help="seconds")
    parser.add_argument("--height", type=float, default=0.03, help="start and end height above the surface, m")
    parser.add_argument("--depth", type=float, default=0.0015, help="how far the stylus presses in, m")
    parser.add_argument("--slide-length", type=float, default=0.08, help="path length along the surface, m")
    parser.add_argument("--keyframe-rate", type=float, default=100.0, help="surface projections per second")
    parser.add_argument("--start", type=float, nargs=3, help="a point to project onto the mesh for the contact")
    parser.add_argument("--direction", type=float, nargs=3, help="slide direction (projected on the surface)")
    parser.add_argument("--compression", choices=("none", "bz2", "lz4"), default="bz2")
    parser.add_argument("--stamp", type=float, default=1700000000.0, help="header stamp of the first pose, s")
    args = parser.parse_args(argv)
    for name in ("rate", "approach", "press", "slide", "retract", "height", "slide_length", "keyframe_rate", "scale"):
        if not getattr(args, name) > 0:
            parser.error("--%s must be positive" % name.replace("_", "-"))
    if not args.depth >= 0:
        parser.error("--depth must be >= 0")

    try:
        verts, tris = read_mesh(args.mesh, args.scale)
    except (OSError, ValueError, IndexError) as e:
        print("generate_stylus_bag: cannot read mesh %s: %s" % (args.mesh, e), file=sys.stderr)
        return 1
    surface = Surface(verts, tris)
    positions, phases, c0, n0 = build_motion(surface, args)

    with rosbag.Bag(args.out, "w", compression=args.compression) as bag:
        msg = PoseStamped()
        msg.header.frame_id = args.frame
        msg.pose.orientation.w = 1.0
        for k, p in enumerate(positions):
            stamp = rospy.Time.from_sec(args.stamp + k / args.rate)
            msg.header.seq = k
            msg.header.stamp = stamp
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = p
            bag.write(args.topic, msg, stamp)
    duration = (len(positions) - 1) / args.rate
    print("generate_stylus_bag: %s: %d poses at %.0f Hz, %.2f s on %s (frame %s); mesh %s, %d triangles, size %.3f m; "
          "contact at (%.4f, %.4f, %.4f) normal (%.2f, %.2f, %.2f); phases %s"
          % (args.out, len(positions), args.rate, duration, args.topic, args.frame, args.mesh, len(tris), surface.size,
             c0[0], c0[1], c0[2], n0[0], n0[1], n0[2], ", ".join("%s %.2f s" % (n, d) for d, n in phases)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
