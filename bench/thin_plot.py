#!/usr/bin/python3
"""Pictures of thin_bench's spheres: a plate seen edge-on, a cross-section through the legs and a thin plate seen
face-on.

usage: thin_plot.py DIR   (reads DIR/thin_spheres.csv, writes DIR/thin_tightness.png)
"""
import csv
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

KINDS = [("medial-reference", "medial reference"), ("clod-tight", "tight"), ("clod-tight-whole", "tight, whole triangles"),
         ("octree", "octree")]
PLATE, PLATE_HALF = "plate-0.015-mixed", (0.4, 0.0075)
LEGS, SECTION_Z = "legs", -0.1
FACE, FACE_HALF = "plate-0.005", (0.4, 0.25)


def load(path):
    spheres = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            spheres.setdefault((row["model"], row["kind"]), []).append(
                tuple(float(row[k]) for k in ("x", "y", "z", "r")))
    return spheres


def leg_centres():
    # thin_models.cpp: legs from (x, y, 0.2) to (1.1 x, 1.3 y, -0.4), radius 0.02.
    out = []
    for k in range(4):
        x, y = (-0.22 if k < 2 else 0.22), (-0.09 if k % 2 else 0.09)
        f = (0.2 - SECTION_Z) / 0.6
        out.append((x + f * 0.1 * x, y + f * 0.3 * y))
    return out


def plate(ax, half, filled, spheres, axis, ylim, title):
    """A plate's rectangle (half sizes) and the spheres' circles in the plane of x and coordinate axis (1: y, 2: z)."""
    ax.add_patch(Rectangle((-half[0], -half[1]), 2 * half[0], 2 * half[1], fill=filled, color="k"))
    for sphere in spheres:
        ax.add_patch(Circle((sphere[0], sphere[axis]), sphere[3], fill=False, lw=0.5, color="tab:red"))
    ax.set_xlim(-0.5, 0.5)
    ax.set_ylim(-ylim, ylim)
    ax.set_aspect("equal")
    ax.set_title(title % len(spheres), fontsize=9)


def main(directory):
    spheres = load(directory + "/thin_spheres.csv")
    fig, axes = plt.subplots(3, len(KINDS), figsize=(5 * len(KINDS), 10.5))
    for col, (kind, label) in enumerate(KINDS):
        plate(axes[0][col], PLATE_HALF, True, spheres.get((PLATE, kind), []), 2, 0.25,
              label + ": plate 0.015 seen edge-on, %d spheres")
        ax = axes[1][col]
        for cx, cy in leg_centres():
            ax.add_patch(Circle((cx, cy), 0.02, color="k"))
        s = spheres.get((LEGS, kind), [])
        cut = 0
        for x, y, z, r in s:
            h = SECTION_Z - z
            if abs(h) < r:
                cut += 1
                ax.add_patch(Circle((x, y), math.sqrt(r * r - h * h), fill=False, lw=0.6, color="tab:blue"))
        ax.set_xlim(-0.4, 0.4)
        ax.set_ylim(-0.25, 0.25)
        ax.set_aspect("equal")
        ax.set_title("%s: legs (0.04 thick) cut at z = %.1f, %d spheres cut" % (label, SECTION_Z, cut), fontsize=9)
        plate(axes[2][col], FACE_HALF, False, spheres.get((FACE, kind), []), 1, 0.32,
              label + ": plate 0.005 seen face-on, %d spheres")
    fig.tight_layout()
    fig.savefig(directory + "/thin_tightness.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
