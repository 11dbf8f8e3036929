#!/usr/bin/env python3
"""Writes the bundled default mesh: a torus with a bump, as an OBJ (no data from outside the repo).

Usage: make_torus_mesh.py OUT.obj [--rings 48] [--sides 24]
The tube gives every triangle an opposite triangle, so the paper's sphere placement runs fully.
"""
import argparse
import math


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("out")
    parser.add_argument("--rings", type=int, default=48)
    parser.add_argument("--sides", type=int, default=24)
    parser.add_argument("--major", type=float, default=0.06, help="major radius in metres")
    parser.add_argument("--minor", type=float, default=0.022, help="tube radius in metres")
    args = parser.parse_args()
    verts, faces = [], []
    for i in range(args.rings):
        u = 2 * math.pi * i / args.rings
        for j in range(args.sides):
            v = 2 * math.pi * j / args.sides
            # A bump on the outer rim makes the shape less regular than a plain torus.
            r = args.minor * (1.0 + 0.25 * math.exp(-((u - math.pi) ** 2) / 0.3) * max(0.0, math.cos(v)))
            x = (args.major + r * math.cos(v)) * math.cos(u)
            y = (args.major + r * math.cos(v)) * math.sin(u)
            z = r * math.sin(v)
            verts.append((x, y, z))
    for i in range(args.rings):
        for j in range(args.sides):
            a = i * args.sides + j
            b = ((i + 1) % args.rings) * args.sides + j
            c = ((i + 1) % args.rings) * args.sides + (j + 1) % args.sides
            d = i * args.sides + (j + 1) % args.sides
            faces.append((a, b, c))
            faces.append((a, c, d))
    with open(args.out, "w") as f:
        f.write("# clod_haptics default mesh: torus with a bump, %d triangles, metres\n" % len(faces))
        for x, y, z in verts:
            f.write("v %.6f %.6f %.6f\n" % (x, y, z))
        for a, b, c in faces:
            f.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))


if __name__ == "__main__":
    main()
