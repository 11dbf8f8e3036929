#!/usr/bin/python3
"""Markdown table of thin_bench's results: per model and target count, each kind's spheres and outside volume.

usage: thin_report.py DIR   (reads DIR/thin_tightness.csv, writes DIR/thin_tightness.md)
"""
import csv
import sys


OPEN = {"mesh_with_border.off"}  # a sheet with a border: outside volume is not defined


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def main(directory):
    data = rows(directory + "/thin_tightness.csv")
    groups = {}
    for r in data:
        groups.setdefault((r["model"], r["target"]), {})[r["kind"]] = r
    out = ["| model | triangles | target | medial ref: spheres, outside, covered | medial grown to cover: outside, covered "
           "| tight: spheres, outside, covered, build ms | tight / medial | tight / grown | octree: spheres, outside "
           "| tight / octree | single-link: spheres, outside | tight, whole triangles: spheres, outside | met |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (model, target), k in groups.items():
        m, g, t, o, s = k["medial-reference"], k["medial-grown"], k["clod-tight"], k["octree"], k["clod-single-link"]
        mo, go, to, oo = (float(x["outside_volume_rel"]) for x in (m, g, t, o))
        # Met: every sample covered, no more spheres than the medial reference, and at most 0.8 times the better of
        # the two references that cover the surface (the medial one grown to cover it, the octree). An open mesh has
        # no inside: no verdict.
        met = float(t["surface_covered"]) == 1.0 and to <= 0.8 * min(go, oo) and int(t["spheres"]) <= int(m["spheres"])
        verdict = "open mesh" if model in OPEN else ("yes" if met else "no")
        b = k.get("clod-tight-whole")
        out.append("| %s | %s | %s | %s, %.3g, %.2f%% | %.3g, %.2f%% | %s, %.3g, %.2f%%, %.1f | %.2f | %.2f | %s, %.3g | %.2f "
                   "| %s, %.3g | %s | %s |" % (
                       model, t["triangles"], target, m["spheres"], mo, 100 * float(m["surface_covered"]), go,
                       100 * float(g["surface_covered"]), t["spheres"], to, 100 * float(t["surface_covered"]),
                       float(t["build_ms"]), to / mo, to / go, o["spheres"], oo, to / oo, s["spheres"],
                       float(s["outside_volume_rel"]),
                       ("%s, %.3g" % (b["spheres"], float(b["outside_volume_rel"]))) if b else "", verdict))
    text = "\n".join(out) + "\n"
    with open(directory + "/thin_tightness.md", "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main(sys.argv[1])
