#!/usr/bin/env python3
"""Turns the CSV files of clod_bench into bench/results/report.md and PNG plots.

Usage: python3 bench/report.py RESULTS_DIR
Reads run.csv, build.csv, sweep.csv, peers.csv, tightness.csv, growth.csv, reference_check.csv and the
contact section's contact.csv, startup.csv, contact_run.csv (any missing file just drops its section).
Ratios are always between figures of the same run.
"""
import csv
import math
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

HEADLINE_MESH = "mannequin-devil.off"
PEERS = ["embree", "cgal", "fcl", "brute"]
MODES = ["spheres", "paper", "exact"]
CLODS = ["clod-grid", "clod-grid-cache", "clod-hierarchy", "clod-flat"]
LEVELS = ["grid", "hierarchy", "flat"]


def ours_for(probe_set):
    """Our contender on a probe set: the grid, with its QueryCache on the stylus trajectory."""
    return "clod-grid-cache" if probe_set == "trajectory" else "clod-grid"


# The sets where the headline compares the shallow points only: there ours is the cached stream, whose deep
# points (see DEEP_WORDS) are a different question from the stateless contenders'.
SHALLOW_SETS = {"trajectory"}
DEEP_WORDS = ("the centre more than r behind the surface after an answer with the centre inside: the cached stream "
              "follows the push there (ClodDetector::query's deep search: the nearest triangle through the grid level's tree over the mesh) and answers "
              "contact, where the stateless contenders and reference answer free")


def compared_median(r):
    """The median the headline compares: on SHALLOW_SETS the shallow points' (older CSVs: all points)."""
    if r["set"] in SHALLOW_SETS and not math.isnan(num(r.get("shallow_median_ns"))):
        return num(r["shallow_median_ns"])
    return num(r["median_ns"])


def deep_of(pr):
    """(deep points, points) of the cached contender's row in a {peer: row} dict, or None."""
    c = pr.get("clod-grid-cache")
    if not c or c.get("deep_probes") in (None, ""):
        return None
    return int(c["deep_probes"]), int(c["probes"])


def read(out, name):
    path = os.path.join(out, name)
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def num(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def f(v, digits=3):
    """Compact number for tables."""
    v = num(v)
    if math.isnan(v):
        return "-"
    if v == 0:
        return "0"
    if abs(v) >= 1e5 or abs(v) < 1e-3:
        return f"{v:.{digits - 1}e}"
    if abs(v) >= 100:
        return f"{v:.0f}"
    return f"{v:.{digits}g}"


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def fit_exponent(xs, ys):
    """Least-squares slope of log y against log x."""
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x > 0 and y > 0]
    if len(pts) < 2:
        return float("nan")
    a = np.array(pts)
    return float(np.polyfit(a[:, 0], a[:, 1], 1)[0])


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "results")
    meta = {r["key"]: r["value"] for r in read(out, "run.csv")}
    build = read(out, "build.csv")
    sweep = read(out, "sweep.csv")
    peers = read(out, "peers.csv")
    tight = read(out, "tightness.csv")
    growth = read(out, "growth.csv")
    checks = read(out, "reference_check.csv")
    meshes = []
    for r in build + peers + sweep:
        if r["mesh"] not in meshes:
            meshes.append(r["mesh"])
    report_d = meta.get("report_d", "0.02")
    md = []
    md.append("# clod_haptics benchmark: run time against error, beside the peers\n")
    md.append(
        f"Run {meta.get('date', '?')} ({meta.get('mode', '?')} mode) on `{meta.get('host', '?')}`, "
        f"{meta.get('cpu', '?')}, {meta.get('hardware_threads', '?')} hardware threads, shared with other jobs"
        + (f" ({f(meta['seconds'])} s, sections {meta.get('sections', '?')}; load average "
           f"{meta.get('loadavg_before', '?')} before and {meta.get('loadavg_after', '?')} after, 1, 5, 15 min)"
           if "seconds" in meta else "") + ": "
        "absolute times drift, so compare the ratios, which are measured in the same run, contender after "
        f"contender on the same probes ({meta.get('rounds', '1')} alternating rounds, best median kept).\n"
    )
    md.append(
        f"Pointer radius r = {meta.get('radius', '?')} on models normalised to the unit cube. Probe sets per mesh: "
        f"`near` ({meta.get('probes_per_set', '?')} surface samples pushed along the normal by up to "
        f"+-{meta.get('near_offset', '?')}), `uniform` ({meta.get('probes_per_set', '?')} points in the bounding box "
        f"grown by {meta.get('uniform_margin', '?')}), `trajectory` (the recorded Geomagic Touch stylus, "
        f"{meta.get('trajectory', '?')}, scaled uniformly into the mesh's bounding box and centred), and "
        "`near-morton` (the near set sorted along a Morton curve: a coherent stream). Every query is timed alone "
        "with the fenced time-stamp counter, the timer's own cost subtracted; the answers are kept and compared "
        "with the exact reference.\n"
    )
    md.append("**Ours** in the comparisons: the grid fast level (`FastLevel::Grid`, gridRadius = r), stateless "
              "(`clod-grid`) on the near, uniform and near-morton probes, and with one `QueryCache` for the stream "
              "(`clod-grid-cache`) on the stylus trajectory (compared on its shallow points: see the QueryCache "
              "table under the headline); the hierarchy and the flat list are shown beside it.\n")
    md.append("Reproduce: `make bench` (full, writes this directory) or `BENCH_QUICK=1 make bench` "
              "(minutes, writes bench/results/tmp/quick).\n")

    # ------------------------------------------------------------------ targets
    md.append("## Issue 5's targets, as measured in this run\n")
    md.append(targets(build, sweep, peers, tight, growth))

    # ------------------------------------------------------------------ reference check
    if checks:
        bad = sum(int(r["differences_from_bruteForceQuery"]) for r in checks)
        n = sum(int(r["probes"]) for r in checks)
        md.append(
            f"**Reference.** The error columns use a pruned exact reference (a grid over the triangles' boxes "
            f"grown by r, same closest-point routine and tie rule as `bruteForceQuery`). In this run it differs "
            f"from `bruteForceQuery` on {bad} of {n} probes checked (bit for bit: contact, distance, point, "
            "triangle).\n"
        )

    # ------------------------------------------------------------------ headline
    def peer_rows(mesh, s):
        return {r["peer"]: r for r in peers if r["mesh"] == mesh and r["set"] == s}

    if peers:
        md.append("## Headline: exact mode, d = %s, r = %s\n" % (report_d, meta.get("radius", "?")))
        rows = []
        for mesh in meshes:
            for s in ["near", "uniform", "trajectory", "near-morton"]:
                pr = peer_rows(mesh, s)
                o = ours_for(s)
                if o not in pr:
                    continue
                ours = compared_median(pr[o])
                fastest = min(
                    (compared_median(pr[p]), p) for p in ["embree", "cgal", "fcl"] if p in pr)
                dp = deep_of(pr)
                label = f"{s} (shallow: {dp[1] - dp[0]} of {dp[1]})" if s in SHALLOW_SETS and dp and dp[0] else s
                row = [mesh, pr[o]["triangles"], pr[o]["spheres"], label, f"**{f(ours)}** ({o[5:]})"]
                for p in CLODS:
                    row.append(f(compared_median(pr[p])) if p in pr else "-")
                for p in PEERS:
                    row.append(f"{f(compared_median(pr[p]))} ({f(compared_median(pr[p]) / ours)}x)" if p in pr else "-")
                row.append(f"{fastest[1]} {f(fastest[0] / ours)}x")
                row.append(" ".join(f"{p[5:] if p.startswith('clod-') else p}:{pr[p]['disagreements']}"
                                    for p in CLODS + PEERS if p in pr))
                rows.append(row)
        md.append(
            "Median ns per query. **Ours** is `clod-grid` (the grid fast level, `FastLevel::Grid` with gridRadius = r, "
            "stateless) on the `near`, `uniform` and `near-morton` probes, and `clod-grid-cache` (the same detector "
            "with one `QueryCache` for the stream, reset at the start of every timed run, probes in their recorded "
            "order) on the `trajectory`, the stylus stream the cache is for. The other variants of ours are shown "
            "beside it: grid, grid with cache, hierarchy, flat list (same sphere set). In brackets: the peer's median "
            "divided by ours (above 1: we are faster). `disagree` counts answers that differ from the reference "
            "(contact flag, or distance / point by more than 1e-9) on the probes each contender ran (the flat list "
            "and brute force run a time-bounded prefix): `grid-cache` against the stream's reference (deep "
            "penetration, `streamReference`), every other contender against the stateless one. On the trajectory "
            "every median is over the shallow points only (the same question for every contender); the deep points, "
            f"{DEEP_WORDS}, are in the next table. On the other sets the `grid+cache` column includes its deep "
            "points.\n"
        )
        md.append(table(["mesh", "tris", "spheres", "probes", "ours", "grid", "grid+cache", "hierarchy", "flat"]
                        + PEERS + ["vs fastest peer", "disagree"], rows))
        pr = peer_rows(HEADLINE_MESH, "near")
        if "clod-grid" in pr:
            ours = num(pr["clod-grid"]["median_ns"])
            fast = min((num(pr[p]["median_ns"]), p) for p in ["embree", "cgal", "fcl"] if p in pr)
            tr = peer_rows(HEADLINE_MESH, "trajectory")
            traj = tr.get("clod-grid-cache")
            md.append(
                f"Targets on {HEADLINE_MESH}: median under 500 ns on near-surface probes: **{f(ours)} ns, "
                f"{'met' if ours < 500 else 'not met'}**; at least 3x faster than the fastest peer ({fast[1]}, "
                f"{f(fast[0])} ns): **{f(fast[0] / ours)}x, {'met' if fast[0] / ours >= 3 else 'not met'}**"
                + (f"; trajectory (grid with cache) under 200 ns: {trajectory_words(tr)}" if traj else "") + ".\n")
    srows = stream_rows(peers, meshes)
    if srows:
        md.append("### QueryCache on its streams: shallow and deep points\n")
        md.append(
            "`clod-grid-cache` runs every probe set as one stream. Deep points: " + DEEP_WORDS + ". Shallow: the "
            "others, the same question for every contender. `searched`: shallow points where the cache still "
            "searched beyond r (after an inside answer, no triangle within r and the centre outside: free for "
            "everyone, found by the deep search): frequent where the stream jumps across the model (`near` and "
            "`uniform` are shuffled, the Morton order still jumps between cells), none on the trajectory. Median / mean ns of the cache on all, shallow and deep points, "
            "beside the stateless grid and Embree on the shallow points (on the deep ones they answer free "
            "cheaply: `deep_median_ns` in peers.csv). Embree/cache: the ratio of the shallow medians.\n")
        md.append(table(["mesh", "probes", "points", "deep", "searched", "cache all", "cache shallow", "cache deep",
                         "no cache shallow", "Embree shallow", "Embree/cache shallow"], srows))

    # ------------------------------------------------------------------ Table 2 per mesh
    if build:
        md.append("## Table 2 per mesh: CLOD levels, detection time and update rate\n")
        md.append(
            "As the paper's Table 2: centres before clustering, spheres after, step reduction (against the previous "
            "d) and total reduction (against the centres). Times are means over the `near` probes, in ns, with the "
            "slowest 1% dropped (preemption spikes on a shared machine; raw means in sweep.csv), per fast level: "
            "grid (the default, gridRadius = r, no cache), hierarchy, flat list. fast = "
            "`spheres` mode (the fast level alone), precise = `exact` minus `spheres`, total = `exact`; update rate = "
            "1 / total. Build = placement (once per mesh) + clustering of this level, ms; det. ms = construction of "
            "the detector for that fast level. Spheres hit and triangles "
            "tested: means per exact query as the detector reports them (what the speed work can cut). A negative "
            "precise time means the `spheres` mode costs more than `exact`: it reports every sphere the pointer "
            "overlaps, while `exact` prunes spheres by its shrinking search radius.\n")
        sw = defaultdict(dict)
        for r in sweep:
            if r["set"] == "near":
                sw[(r["mesh"], r["d"], r["level"])][r["mode"]] = r
        for mesh in meshes:
            rows = []
            for b in [r for r in build if r["mesh"] == mesh]:
                row = [b["d"], b["centres"], b["spheres"], f"{100 * num(b['step_reduction']):.1f}%",
                       f"{100 * num(b['total_reduction']):.1f}%", f(num(b["placement_ms"]) + num(b["build_ms"]))]
                for level in LEVELS:
                    m = sw.get((mesh, b["d"], level), {})
                    if "exact" in m and "spheres" in m:
                        fast, tot = num(m["spheres"]["trimmed_mean_ns"]), num(m["exact"]["trimmed_mean_ns"])
                        row += [f(fast), f(tot - fast), f(tot), f(1e9 / tot), f(m["exact"]["detector_build_ms"])]
                    else:
                        row += ["-"] * 5
                    if level != "flat":
                        row.append(f"{f(m['exact']['mean_spheres_hit'])} / {f(m['exact']['mean_tris_tested'])}"
                                   if "exact" in m else "-")
                rows.append(row)
            if rows:
                tris = next(r["triangles"] for r in build if r["mesh"] == mesh)
                md.append(f"### {mesh} ({tris} triangles)\n")
                hdr = ["d", "centres", "spheres", "step red.", "total red.", "build ms"]
                for level, short in [("grid", "grid"), ("hierarchy", "hier."), ("flat", "flat")]:
                    hdr += [f"{short} fast", f"{short} precise", f"{short} total", f"{short} Hz", f"{short} det. ms"]
                    if level != "flat":
                        hdr.append(f"{short} exact: spheres hit / tris tested")
                md.append(table(hdr, rows))

    # ------------------------------------------------------------------ errors
    if sweep:
        md.append("## Error against the exact reference, per mode\n")
        md.append(
            "Over the `near`, `uniform` and `trajectory` probes together, hierarchy fast level (the flat list "
            "answers the same questions; its columns are in sweep.csv). missed = reference contact not reported, "
            "false = contact reported where the reference has none, both as counts over the probes; distance error "
            "|ours - reference| and normal error (degrees) over the probes both call a contact. `spheres` reports the "
            "contact with the clustered spheres, so its distance is to a sphere, not to the surface.\n")
        exact_bad = []
        for r in sweep:
            if r["mode"] == "exact" and (int(r["missed"]) or int(r["false_contacts"]) or num(r["max_dist_err"]) > 0):
                exact_bad.append(r)
        for other in ["grid", "flat"]:
            flat = [r for r in sweep if r["level"] == other and "contact_diff_vs_hierarchy" in r]
            if not flat:
                continue
            differ = defaultdict(int)
            for r in flat:
                differ[r["mode"]] += int(r["contact_diff_vs_hierarchy"]) + (
                    int(r["distance_diff_vs_hierarchy"]) if r["mode"] != "spheres" else 0)
            md.append(
                f"**{other.capitalize()} against hierarchy** (same spheres, other fast level), answers that differ on "
                f"the probes the {other} level ran (%d probes over all rows): " % sum(int(r["probes"]) for r in flat)
                + ", ".join(f"{m} {differ[m]}" for m in MODES)
                + " (contact flag, or distance by more than 1e-12; spheres mode compares the flag only, the sphere "
                "it reports may differ).\n")
        md.append("Where these counts are zero, the error columns of the hierarchy below hold for every fast level.\n")
        md.append(
            "**Exact mode errors on every mesh, level, d and probe set: "
            + ("all zero.**\n" if not exact_bad else f"{len(exact_bad)} rows not zero (see sweep.csv).**\n"))
        for mesh in meshes:
            agg = defaultdict(lambda: defaultdict(float))
            for r in sweep:
                if r["mesh"] != mesh or r["level"] != "hierarchy" or r["set"] == "near-morton":
                    continue
                a = agg[(r["d"], r["mode"])]
                both = min(int(r["ref_contacts"]), int(r["contacts"])) - 0  # weight for means (approx.)
                a["n"] += int(r["probes"])
                a["ref"] += int(r["ref_contacts"])
                a["missed"] += int(r["missed"])
                a["false"] += int(r["false_contacts"])
                a["w"] += both
                a["dist"] += num(r["mean_dist_err"]) * both
                a["normal"] += num(r["mean_normal_err_deg"]) * both
                a["maxdist"] = max(a["maxdist"], num(r["max_dist_err"]))
                a["maxnormal"] = max(a["maxnormal"], num(r["max_normal_err_deg"]))
            ds = sorted({k[0] for k in agg}, key=num)
            rows = []
            for d in ds:
                row = [d]
                for mode in MODES:
                    a = agg.get((d, mode))
                    if not a:
                        row += ["-"] * 3
                        continue
                    w = max(a["w"], 1)
                    row += [f"{int(a['missed'])} / {int(a['false'])}", f"{f(a['dist'] / w)} / {f(a['maxdist'])}",
                            f"{f(a['normal'] / w)} / {f(a['maxnormal'])}"]
                rows.append(row)
            if rows:
                n = agg[(ds[0], "exact")]["n"] if (ds[0], "exact") in agg else 0
                ref = agg[(ds[0], "exact")]["ref"] if (ds[0], "exact") in agg else 0
                md.append(f"### {mesh} ({int(n)} probes, {int(ref)} reference contacts)\n")
                hdr = ["d"]
                for mode in MODES:
                    hdr += [f"{mode} missed / false", f"{mode} dist err mean / max", f"{mode} normal err deg mean / max"]
                md.append(table(hdr, rows))
        plot_pareto(out, sweep, meshes)
        md.append("![run time against error](pareto.png)\n")
        md.append(
            "pareto.png: mean query time (slowest 1% dropped) (near + uniform + trajectory probes) against the fraction of wrong contact "
            "answers (missed + false over the probes), one point per d, per mode (colour) and fast level (marker and "
            "line: grid solid squares, hierarchy dashed circles, flat dotted crosses). "
            "Exact sits at zero error for every d.\n")

    # ------------------------------------------------------------------ peers plot
    if peers:
        plot_peers(out, peers, meshes)
        md.append("## Ratio to each peer\n![ratio to peers](peers.png)\n")
        md.append("peers.png: the peer's median time divided by ours (exact, d = %s; ours = grid, with its cache on "
                  "the trajectory, where every median is over the shallow points) per probe set, with our hierarchy "
                  "and flat list as well; above the line at 1 ours "
                  "is faster.\n" % report_d)
        rows = []
        for mesh in meshes:
            pr = peer_rows(mesh, "near")
            if pr:
                rows.append([mesh] + [f"{f(pr[p]['build_ms'])}" if p in pr else "-"
                                      for p in ["clod-grid", "clod-hierarchy", "clod-flat", "embree", "cgal", "fcl"]])
        md.append("Structure build times, ms (ours: `ClodDetector` construction on the d = %s sphere set, not the "
                  "sphere set itself):\n" % report_d)
        md.append(table(["mesh", "clod grid", "clod hierarchy", "clod flat", "embree", "cgal", "fcl"], rows))

    # ------------------------------------------------------------------ tightness
    if tight:
        md.append("## Sphere tightness against an octree of the same sphere count (paper Figs. 17 to 19)\n")
        md.append(
            "Octree: the cube around the mesh split into eight, keeping the cells an exact triangle-box test finds "
            "occupied, largest cells first, until at least as many cells as our spheres; each cell gives its "
            "circumscribed sphere (Bradshaw's octree spheres). Outside: volume of the union of the spheres outside "
            "the mesh; union: volume of the union; both relative to the mesh volume and estimated by Monte Carlo "
            "(a sphere drawn in proportion to its volume, a point uniform in it, weighted by 1 / the number of "
            "spheres containing it; inside test: non-zero winding number along a ray, majority of three "
            "directions). The mesh volume is the same test's Monte Carlo volume in the bounding box (`MC vol`), "
            "shown beside the divergence-theorem volume: equal on closed meshes, not on meshes with holes, where "
            "the divergence volume is not defined. Volumes only for meshes with at most 3% of their edges open. "
            "Covered: fraction of surface samples inside some sphere (ours must be 1). Issue 5's target: 100% "
            "covered with an outside volume at most 0.40 (Hubbard's) at a comparable sphere count. Ours twice, on the "
            "same ray-cast placement: single-link clustering (`clod`, the default) and the cube clustering "
            "(`clod-cube`, `makeClustering(\"cube\")`); the octree has the single-link set's sphere count. Build ms: "
            "a fresh ClodBuilder (placement on all hardware threads, then build(d) of that level), best of three "
            "runs (single runs on this shared machine mostly measure the other jobs).\n")
        md.append(
            "The tight clustering (`clod-tight`, `makeClustering(\"tight\")`, same placement) in a table of its own, "
            "beside an octree of its own sphere count (`octree-tight`): the surface split top-down into patches, "
            "each sphere centred deep inside and kept when its cap beyond the surface holds at most a ball of "
            "radius d. Its d is that radius, not the single-link distance: compare rows by sphere count.\n")
        by = defaultdict(dict)
        for r in tight:
            by[(r["mesh"], r["d"])][r["kind"]] = r
        rows = []
        for (mesh, d), k in by.items():
            c, o, q = k.get("clod"), k.get("octree"), k.get("clod-cube")
            if not c or not o:
                continue
            row = [mesh, d, c["spheres"], f(c["outside_volume_rel"]), f(c["union_volume_rel"]),
                   f"{num(c['surface_covered']):.6f}", f(c["build_ms"])]
            if q:
                row += [q["spheres"], f(q["outside_volume_rel"]), f(q["union_volume_rel"]),
                        f"{num(q['surface_covered']):.6f}", f(q["build_ms"])]
            else:
                row += ["-"] * 5
            row += [o["spheres"], o["octree_depth"], f(o["outside_volume_rel"]), f(o["union_volume_rel"]),
                    f"{num(o['surface_covered']):.6f}", f"{f(c['mc_mesh_volume'])} / {f(c['mesh_volume'])}",
                    c["open_edges"]]
            rows.append(row)
        md.append(table(["mesh", "d", "single-link spheres", "outside", "union", "covered", "build ms",
                         "cube spheres", "cube outside", "cube union", "cube covered", "cube build ms",
                         "octree spheres", "depth", "octree outside", "octree union", "octree covered",
                         "MC vol / exact", "open edges"], rows))
        rows = []
        for (mesh, d), k in by.items():
            t, o = k.get("clod-tight"), k.get("octree-tight")
            if not t or not o:
                continue
            rows.append([mesh, d, t["spheres"], f(t["outside_volume_rel"]), f(t["union_volume_rel"]),
                         f"{num(t['surface_covered']):.6f}", f(t["build_ms"]), o["spheres"], o["octree_depth"],
                         f(o["outside_volume_rel"]), f(o["union_volume_rel"]), f"{num(o['surface_covered']):.6f}"])
        if rows:
            md.append(table(["mesh", "d", "tight spheres", "tight outside", "tight union", "tight covered",
                             "tight build ms", "octree spheres", "depth", "octree outside", "octree union",
                             "octree covered"], rows))
        plot_tightness(out, tight)
        md.append("![tightness](tightness.png)\n")

    # ------------------------------------------------------------------ growth
    if growth:
        md.append("## Growth with the triangle count\n")
        md.append(
            "The meshes subdivided (midpoint split of every triangle into four, repeatedly), each point measured "
            "in a forked process. Build = `ClodBuilder` construction (ray-cast placement, all hardware threads) + "
            "`build(d)`; detector = `ClodDetector` construction with the grid fast level (gridRadius = r), the "
            "detector the queries run on. Query: median over near-surface probes, exact mode, grid, no cache. Peak = the larger "
            "VmHWM of the builder phase and of the detector's construction minus VmRSS before the build (peak reset "
            "through /proc/self/clear_refs), per triangle, for the whole CLOD set (builder, set and detector alive "
            "together); retained = resident after the builder is freed; set = the sphere set's arrays alone; "
            "detector heap = bytes the detector keeps allocated (mallinfo2, grid and trees included), detector peak = "
            "VmHWM during its construction minus VmRSS before it; builder peak = the builder phase alone (placement "
            "and build(d), before any detector); hierarchy detector = a `FastLevel::Hierarchy` detector built on the "
            "same set afterwards, for comparison (time, heap kept). `check` = probes compared with the reference "
            "(mismatches).\n")
        rows = []
        for g in growth:
            rows.append([g["mesh"], g["subdivisions"], g["triangles"], g["spheres"], f(g["placement_ms"]),
                         f(g["build_ms"]), f(g["detector_ms"]), f(g["build_tri_per_s"]), f(g["median_ns"]),
                         f(g["peak_bytes_per_tri"]), f(g["retained_bytes_per_tri"]), f(g["set_bytes_per_tri"]),
                         f(g.get("builder_peak_bytes_per_tri")),
                         f(g.get("detector_heap_bytes_per_tri")), f(g.get("detector_peak_bytes_per_tri")),
                         f"{f(g.get('hierarchy_detector_ms'))} / {f(g.get('hierarchy_detector_heap_bytes_per_tri'))}",
                         f"{g['checked']} ({g['mismatches']})"])
        md.append(table(["mesh", "subdiv.", "tris", "spheres", "placement ms", "build(d) ms", "grid detector ms",
                         "build tri/s", "query ns", "peak B/tri", "retained B/tri", "set B/tri", "builder peak B/tri",
                         "grid detector heap B/tri", "grid detector peak B/tri", "hierarchy detector ms / heap B/tri",
                         "check"], rows))
        rows = []
        allx, ally, allb, alld = [], [], [], []
        for mesh in dict.fromkeys(g["mesh"] for g in growth):
            gs = [g for g in growth if g["mesh"] == mesh]
            x = [num(g["triangles"]) for g in gs]
            q = [num(g["median_ns"]) for g in gs]
            b = [num(g["placement_ms"]) + num(g["build_ms"]) for g in gs]
            dt = [num(g["detector_ms"]) for g in gs]
            allx += x
            ally += q
            allb += b
            alld += dt
            rows.append([mesh, f"{fit_exponent(x, b):.2f}", f"{fit_exponent(x, dt):.2f}", f"{fit_exponent(x, q):.2f}"])
        rows.append(["all points", f"{fit_exponent(allx, allb):.2f}", f"{fit_exponent(allx, alld):.2f}",
                     f"{fit_exponent(allx, ally):.2f}"])
        md.append("Fitted exponents (least squares of log time against log triangles): build time ~ n^a, grid "
                  "detector construction ~ n^c, query time (grid) ~ n^b.\n")
        md.append(table(["mesh", "build a", "detector c", "query b"], rows))
        big = max(growth, key=lambda g: num(g["triangles"]))
        md.append(
            f"Largest mesh: {big['mesh']} x{big['subdivisions']}, {big['triangles']} triangles: build throughput "
            f"{f(big['build_tri_per_s'])} tri/s (target 1e6), peak {f(big['peak_bytes_per_tri'])} B/tri "
            f"(target 300; the builder phase alone {f(big.get('builder_peak_bytes_per_tri'))} B/tri).\n")
        plot_growth(out, growth)
        md.append("![growth](growth.png)\n")

    md += contact_section(out)

    md.append("## Files\n")
    md.append("`build.csv` (levels), `sweep.csv` (every mesh x d x fast level x mode x probe set: times and errors), "
              "`peers.csv`, `tightness.csv`, `growth.csv`, `reference_check.csv`, `run.csv` (settings and machine); "
              "the contact section: `contact.csv`, `startup.csv`, `contact_models.csv`, `contact_run.csv`.\n")
    with open(os.path.join(out, "report.md"), "w") as fo:
        fo.write("\n".join(md))
    print("report written:", os.path.join(out, "report.md"))


def trajectory_words(tr, bold=True):
    """The trajectory target in words, on the comparable (shallow) figures, with the deep points named."""
    c = tr["clod-grid-cache"]
    v = compared_median(c)
    b = "**" if bold else ""
    dp = deep_of(tr)
    if not dp:  # an older peers.csv: no split
        return (f"{b}{f(v)} ns, {'met' if v < 200 else 'not met'}{b} (no cache "
                f"{f(tr['clod-grid']['median_ns']) if 'clod-grid' in tr else '-'} ns; {c['disagreements']} disagreements)")
    e = tr.get("embree")
    return (f"{b}{f(v)} ns on the {dp[1] - dp[0]} shallow points of {dp[1]}, {'met' if v < 200 else 'not met'}{b} "
            f"(no cache {f(compared_median(tr['clod-grid'])) if 'clod-grid' in tr else '-'} ns, Embree "
            f"{f(compared_median(e)) if e else '-'} ns on the same points); the other {dp[0]} points are deep ("
            f"{DEEP_WORDS}): there the cache's median is {f(c['deep_median_ns'])} ns (mean {f(c['deep_mean_ns'])}), "
            f"over all points {f(c['median_ns'])} ns (mean {f(c['mean_ns'])}); {c['disagreements']} disagreements "
            "with the stream's reference")


def stream_rows(peers, meshes):
    rows = []
    for mesh in meshes:
        for s in ["near", "uniform", "trajectory", "near-morton"]:
            pr = {r["peer"]: r for r in peers if r["mesh"] == mesh and r["set"] == s}
            c, g, e = pr.get("clod-grid-cache"), pr.get("clod-grid"), pr.get("embree")
            dp = deep_of(pr)
            if not dp:
                continue

            def mm(r, k):
                return f"{f(r[k + 'median_ns'])} / {f(r[k + 'mean_ns'])}" if r else "-"

            rows.append([mesh, s, dp[1], f"{dp[0]} ({100 * dp[0] / max(1, dp[1]):.0f}%)", c.get("deep_free_probes", "-"),
                         mm(c, ""), mm(c, "shallow_"),
                         mm(c, "deep_") if dp[0] else "-", mm(g, "shallow_"), mm(e, "shallow_"),
                         f(num(e["shallow_median_ns"]) / num(c["shallow_median_ns"])) if e else "-"])
    return rows


def targets(build, sweep, peers, tight, growth):
    rows = []

    def met(ok):
        return "met" if ok else "**not met**"

    pr = {r["peer"]: r for r in peers if r["mesh"] == HEADLINE_MESH and r["set"] == "near"}
    if "clod-grid" in pr:
        ours = num(pr["clod-grid"]["median_ns"])
        rows.append([f"exact, {HEADLINE_MESH}, d = {pr['clod-grid']['d']}, near-surface: median < 500 ns (clod-grid)",
                     f"{f(ours)} ns (hierarchy {f(pr['clod-hierarchy']['median_ns']) if 'clod-hierarchy' in pr else '-'} ns)",
                     met(ours < 500)])
        cand = [(num(pr[p]["median_ns"]), p) for p in ["embree", "cgal", "fcl"] if p in pr]
        if cand:
            fast = min(cand)
            bad = sum(int(pr[p]["disagreements"]) for p in pr)
            rows.append(["... at least 3x faster than the fastest peer, identical answers",
                         f"{fast[1]} {f(fast[0])} ns: {f(fast[0] / ours)}x; {bad} disagreements (all contenders)",
                         met(fast[0] / ours >= 3 and bad == 0)])
    tr = {r["peer"]: r for r in peers if r["mesh"] == HEADLINE_MESH and r["set"] == "trajectory"}
    if "clod-grid-cache" in tr:
        v = compared_median(tr["clod-grid-cache"])
        rows.append(["... on the recorded trajectory with coherence (clod-grid-cache): median < 200 ns, on the "
                     "points every contender answers alike (shallow)", trajectory_words(tr, bold=False), met(v < 200)])
    if sweep:
        bad = [r for r in sweep if r["mode"] == "exact" and (int(r["missed"]) or int(r["false_contacts"])
                                                              or num(r["max_dist_err"]) > 0)]
        rows.append(["exact: error columns all zero on every mesh", f"{len(bad)} rows not zero", met(not bad)])
    # Tightness on the ~20k model at the sphere count closest to Hubbard's 508.
    ours = [r for r in tight if r["mesh"] == HEADLINE_MESH and r["kind"] == "clod"]
    if ours:
        best = min(ours, key=lambda r: abs(math.log(max(num(r["spheres"]), 1) / 508.0)))
        cov = num(best["surface_covered"])
        out = num(best["outside_volume_rel"])
        rows.append([f"tightness, {HEADLINE_MESH}, ~508 spheres: 100% covered, outside <= 0.40",
                     f"d = {best['d']}: {best['spheres']} spheres, covered {cov:.6f}, outside {f(out)}",
                     met(cov == 1.0 and out <= 0.40)])
        b = [r for r in build if r["mesh"] == HEADLINE_MESH and r["d"] == best["d"]]
        if b:
            ms = num(b[0]["placement_ms"]) + num(b[0]["build_ms"])
            rows.append([f"... built in < 50 ms ({b[0]['triangles']} triangles)", f"{f(ms)} ms", met(ms < 50)])
    for kind, label in (("clod-cube", "cube"), ("clod-tight", "tight")):
        kind_rows = [r for r in tight if r["mesh"] == HEADLINE_MESH and r["kind"] == kind]
        if not kind_rows:
            continue
        best = min(kind_rows, key=lambda r: abs(math.log(max(num(r["spheres"]), 1) / 508.0)))
        cov = num(best["surface_covered"])
        out = num(best["outside_volume_rel"])
        rows.append([f"... the same with the {label} clustering ({kind}, ~508 spheres)",
                     f"d = {best['d']}: {best['spheres']} spheres, covered {cov:.6f}, outside {f(out)}, "
                     f"built in {f(best['build_ms'])} ms",
                     met(cov == 1.0 and out <= 0.40 and num(best["build_ms"]) < 50)])
    big = [g for g in growth if num(g["triangles"]) >= 7e5]
    if big:
        tps = [num(g["build_tri_per_s"]) for g in big]
        mem = [num(g["peak_bytes_per_tri"]) for g in big]
        rows.append(["build throughput >= 1e6 tri/s on the ~1M-triangle meshes",
                     f"{f(min(tps))} to {f(max(tps))} tri/s", met(min(tps) >= 1e6)])
        rows.append(["peak memory < 300 B/tri for the whole CLOD set (builder, set and grid detector)",
                     f"{f(min(mem))} to {f(max(mem))} B/tri", met(max(mem) < 300)])
        bp = [num(g.get("builder_peak_bytes_per_tri")) for g in big]
        if not any(math.isnan(v) for v in bp):
            dh = [num(g.get("detector_heap_bytes_per_tri")) for g in big]
            rows.append(["... the builder phase alone (placement + build(d)); grid detector heap kept",
                         f"{f(min(bp))} to {f(max(bp))} B/tri; detector {f(min(dh))} to {f(max(dh))} B/tri",
                         met(max(bp) < 300)])
    return table(["target", "measured", ""], rows)


# ---------------------------------------------------------------------------------------------- plots
def grid(n):
    cols = min(3, max(1, n))
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.2 * rows), squeeze=False)
    return fig, axes.flatten()


def plot_pareto(out, sweep, meshes):
    colours = {"spheres": "tab:orange", "paper": "tab:blue", "exact": "tab:green"}
    used = [m for m in meshes if any(r["mesh"] == m for r in sweep)]
    fig, axes = grid(len(used))
    for ax, mesh in zip(axes, used):
        for level, marker, ls in [("grid", "s", "-"), ("hierarchy", "o", "--"), ("flat", "x", ":")]:
            for mode in MODES:
                pts = defaultdict(lambda: [0.0, 0.0, 0.0])  # d -> time sum, wrong, n
                for r in sweep:
                    if r["mesh"] == mesh and r["level"] == level and r["mode"] == mode and r["set"] != "near-morton":
                        p = pts[num(r["d"])]
                        n = int(r["probes"])
                        p[0] += num(r["trimmed_mean_ns"]) * n
                        p[1] += int(r["missed"]) + int(r["false_contacts"])
                        p[2] += n
                ds = sorted(pts)
                if not ds:
                    continue
                x = [100.0 * pts[d][1] / pts[d][2] for d in ds]
                y = [pts[d][0] / pts[d][2] for d in ds]
                ax.plot(x, y, ls, marker=marker, color=colours[mode], label=f"{mode} {level}", ms=5)
                if level == "grid":
                    for d, xi, yi in zip(ds, x, y):
                        ax.annotate(f"{d:g}", (xi, yi), fontsize=6, alpha=0.7)
        ax.set_yscale("log")
        ax.set_xscale("symlog", linthresh=0.01)  # exact sits at 0; paper's few misses stay visible
        ax.set_xlim(left=-0.002)
        ax.set_xlabel("wrong contact answers, % of probes (symlog)")
        ax.set_ylabel("mean ns per query")
        ax.set_title(mesh, fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[len(used):]:
        ax.axis("off")
    if used:
        axes[0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "pareto.png"), dpi=90)
    plt.close(fig)


def plot_peers(out, peers, meshes):
    sets = ["near", "uniform", "trajectory", "near-morton"]
    used = [m for m in meshes if any(r["mesh"] == m for r in peers)]
    fig, axes = grid(len(used))
    shown = ["clod-hierarchy", "clod-flat"] + PEERS
    width = 0.8 / len(shown)
    for ax, mesh in zip(axes, used):
        pr = defaultdict(dict)
        for r in peers:
            if r["mesh"] == mesh:
                pr[r["set"]][r["peer"]] = compared_median(r)
        for i, p in enumerate(shown):
            ys = [pr[s].get(p, float("nan")) / pr[s].get(ours_for(s), float("nan")) for s in sets]
            ax.bar(np.arange(len(sets)) + (i - (len(shown) - 1) / 2) * width, ys, width, label=p,
                   hatch="//" if p.startswith("clod") else None)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_yscale("log")
        ax.set_xticks(np.arange(len(sets)))
        ax.set_xticklabels([s + "\n(shallow)" if s in SHALLOW_SETS else s for s in sets], fontsize=7)
        ax.set_ylabel("median / ours (grid, +cache on trajectory)", fontsize=7)
        ax.set_title(mesh, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
    for ax in axes[len(used):]:
        ax.axis("off")
    if used:
        axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "peers.png"), dpi=90)
    plt.close(fig)


def plot_tightness(out, tight):
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    styles = {"clod": "-", "clod-cube": "--", "octree": ":", "clod-tight": "-.", "octree-tight": ":"}
    colour = {m: f"C{i % 10}" for i, m in enumerate(dict.fromkeys(r["mesh"] for r in tight))}
    for kind, marker in [("clod", "o"), ("clod-cube", "^"), ("octree", "s"), ("clod-tight", "D"), ("octree-tight", "x")]:
        for mesh in colour:
            rs = [r for r in tight if r["mesh"] == mesh and r["kind"] == kind and not math.isnan(num(r["outside_volume_rel"]))]
            if not rs:
                continue
            rs.sort(key=lambda r: num(r["spheres"]))
            ax.plot([num(r["spheres"]) for r in rs], [num(r["outside_volume_rel"]) for r in rs],
                    styles[kind], marker=marker, color=colour[mesh], label=f"{mesh} {kind}", ms=4)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("spheres")
    ax.set_ylabel("sphere volume outside the mesh / mesh volume")
    ax.set_title("colour: mesh; solid o: single-link, dashed ^: cube, dash-dot D: tight, dotted s/x: octree "
                 "(single-link / tight count)", fontsize=8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "tightness.png"), dpi=90)
    plt.close(fig)


def plot_growth(out, growth):
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for mesh in dict.fromkeys(g["mesh"] for g in growth):
        gs = [g for g in growth if g["mesh"] == mesh]
        x = [num(g["triangles"]) for g in gs]
        axes[0].plot(x, [num(g["median_ns"]) for g in gs], "-o", label=mesh, ms=4)
        axes[1].plot(x, [num(g["placement_ms"]) + num(g["build_ms"]) for g in gs], "-o", label=mesh, ms=4)
        axes[2].plot(x, [num(g["detector_ms"]) for g in gs], "-o", label=mesh, ms=4)
    axes[0].set_ylabel("median ns per query (exact, grid)")
    axes[2].set_ylabel("grid detector construction ms")
    axes[1].set_ylabel("build ms (placement + build(d))")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("triangles")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "growth.png"), dpi=90)
    plt.close(fig)


# ---------------------------------------------------------------------- contact section (issue 18)
SPEEDS = ["0.01", "0.1", "0.5", "2"]


def ratio(a, b):
    a, b = num(a), num(b)
    return a / b if b > 0 else float("nan")


def contact_index(contact):
    """(model, class, contender) -> row."""
    return {(r["model"], r["class"], r["contender"]): r for r in contact}


def contact_preamble(crun, contact):
    bad = sum(int(r["mismatches"]) for r in contact)
    return (
        f"Run {crun.get('date', '?')} ({crun.get('mode', '?')} mode, {crun.get('seconds', '?')} s), "
        f"{crun.get('cpu', '?')}, {crun.get('hardware_threads', '?')} hardware threads; load average "
        f"{crun.get('loadavg_before', '?')} before and {crun.get('loadavg_after', '?')} after (1, 5, 15 min): the "
        "machine is shared, so the absolute times drift; the ratios are measured contender after contender on the "
        f"same probes ({crun.get('rounds', '?')} alternating rounds, the round with the lowest mean kept per "
        "contender).\n\n"
        f"r = {crun.get('radius', '?')}, d = {crun.get('d', '?')}. Ours: `clod-grid` (`ClodDetector`, "
        "`FastLevel::Grid`, gridRadius = r, exact mode, as the nodes and clod_tool build it), and `clod-grid-cache` "
        "(the same with one `QueryCache` per path). Probes per model: "
        f"{crun.get('probes', '?')}: half within 3r of a face (both sides), a quarter near vertices and edges, a "
        "quarter uniform in the box grown by r, classified in contact or free by the exact reference. Every answer "
        f"is checked against the exact reference (contact flag, distance and point to 1e-9): **{bad} mismatches** "
        "over all rows. Ratios are peer / ours: above 1 ours is faster. Models: `contact_models.csv`; "
        "bench/README.md says how they are generated.\n")


def contact_probe_rows(models, idx):
    rows = []
    for m in models:
        def g(cls, who, col):
            r = idx.get((m, cls, who))
            return r[col] if r else "nan"
        rows.append([
            m, g("contact", "clod-grid", "triangles"), g("contact", "clod-grid", "n"),
            f"{f(g('contact', 'clod-grid', 'mean_ns'))} / {f(g('contact', 'clod-grid', 'p99_ns'))}",
            f"{f(g('contact', 'embree', 'mean_ns'))} / {f(g('contact', 'embree', 'p99_ns'))}",
            f"**{f(ratio(g('contact', 'embree', 'mean_ns'), g('contact', 'clod-grid', 'mean_ns')))}** / "
            f"{f(ratio(g('contact', 'embree', 'p99_ns'), g('contact', 'clod-grid', 'p99_ns')))}",
            f"{f(ratio(g('contact', 'cgal', 'mean_ns'), g('contact', 'clod-grid', 'mean_ns')))} / "
            f"{f(ratio(g('contact', 'cgal', 'p99_ns'), g('contact', 'clod-grid', 'p99_ns')))}",
            f"{f(g('free', 'clod-grid', 'mean_ns'))} / {f(g('free', 'clod-grid', 'p99_ns'))}",
            f"{f(ratio(g('free', 'embree', 'mean_ns'), g('free', 'clod-grid', 'mean_ns')))} / "
            f"{f(ratio(g('free', 'embree', 'p99_ns'), g('free', 'clod-grid', 'p99_ns')))}",
            f"{f(ratio(g('free', 'cgal', 'mean_ns'), g('free', 'clod-grid', 'mean_ns')))} / "
            f"{f(ratio(g('free', 'cgal', 'p99_ns'), g('free', 'clod-grid', 'p99_ns')))}",
        ])
    return rows


def contact_path_rows(models, idx):
    rows = []
    for m in models:
        for sp in SPEEDS:
            cls = "path-" + sp
            c, g, e, cg = (idx.get((m, cls, w)) for w in ["clod-grid-cache", "clod-grid", "embree", "cgal"])
            sc, se = idx.get((m, cls + "-shallow", "clod-grid-cache")), idx.get((m, cls + "-shallow", "embree"))
            sg, sgc, _ = cache_pair(idx, m, cls + "-shallow")
            if not (c and g and e):
                continue
            deep = 1.0 - num(sc["n"]) / num(c["n"]) if sc else float("nan")
            rows.append([
                m, sp, f"{100 * deep:.0f}%",
                f"{f(c['mean_ns'])} / {f(c['p99_ns'])}", f"{f(g['mean_ns'])} / {f(g['p99_ns'])}",
                f"{f(e['mean_ns'])} / {f(e['p99_ns'])}",
                f"{f(ratio(e['mean_ns'], c['mean_ns']))} / {f(ratio(e['p99_ns'], c['p99_ns']))}",
                f"{f(ratio(e['mean_ns'], g['mean_ns']))} / {f(ratio(e['p99_ns'], g['p99_ns']))}",
                f"{f(ratio(se['mean_ns'], sc['mean_ns']))} / {f(ratio(se['p99_ns'], sc['p99_ns']))}" if sc and se else "-",
                f"{f(ratio(sg['mean_ns'], sgc['mean_ns']))} / {f(ratio(sg['p99_ns'], sgc['p99_ns']))}" if sgc and sg else "-",
                f"{f(ratio(cg['mean_ns'], c['mean_ns']))} / {f(ratio(cg['p99_ns'], c['p99_ns']))}" if cg else "-",
            ])
    return rows


def cache_pair(idx, m, key):
    """The stateless and the cached rows of one set, interleaved point by point when the run has them (timePaired),
    else the contenders' own rows; and whether they were interleaved."""
    g, c = idx.get((m, key, "clod-grid-paired")), idx.get((m, key, "clod-grid-cache-paired"))
    if g and c:
        return g, c, True
    return idx.get((m, key, "clod-grid")), idx.get((m, key, "clod-grid-cache")), False


def cache_summary(models, idx):
    """The QueryCache against the stateless query on the shallow points of the coherent paths (the same question)."""
    rs = []
    for m in models:
        for sp in SPEEDS:
            sg, sc, paired = cache_pair(idx, m, "path-" + sp + "-shallow")
            if sc and sg:
                rs.append((ratio(sg["mean_ns"], sc["mean_ns"]), m, sp, paired))
    if not rs:
        return ""
    slower = sorted(x for x in rs if x[0] < 1.0)
    worst = ", ".join(f"{m} at {sp} m/s {f(r)}" for r, m, sp, _ in slower[:4])
    how = ("the two interleaved point by point, which one first alternating (`-paired` rows in contact.csv)"
           if all(x[3] for x in rs) else "contender after contender, so a few percent either way is the machine's noise")
    return (f"Shallow points, no cache / cache by the mean (above 1: the cache is faster; {how}): below 1 on "
            f"{len(slower)} of {len(rs)} paths{', below 0.98 on ' + str(sum(x[0] < 0.98 for x in rs)) if slower else ''}"
            f"{' (lowest: ' + worst + ')' if slower else ''}.\n")


def contact_summary(models, idx):
    rs = [ratio(idx[(m, "contact", "embree")]["mean_ns"], idx[(m, "contact", "clod-grid")]["mean_ns"])
          for m in models if (m, "contact", "embree") in idx and (m, "contact", "clod-grid") in idx]
    rs = [x for x in rs if x > 0]
    if not rs:
        return ""
    gm = math.exp(sum(math.log(x) for x in rs) / len(rs))
    return (f"In contact, Embree / ours by the mean: at least 3 on {sum(x >= 3 for x in rs)} of {len(rs)} models, "
            f"above 1 on {sum(x > 1 for x in rs)}; from {f(min(rs))} to {f(max(rs))}, geometric mean {f(gm)}.\n")


def startup_rows(models, startup):
    by = {(r["model"], r["contender"]): r for r in startup}
    rows = []
    for m in models:
        o, q, e, e2, c = (by.get((m, w)) for w in ["clod-grid", "clod-quick", "embree", "embree-2t", "cgal"])
        if not o:
            continue
        rows.append([
            m, o["triangles"], o["spheres"], f(o["ms"]), f(o["ns_per_tri"]), f(o["tri_per_s"]),
            f"{f(o['placement_ms'])} / {f(o['build_ms'])} / {f(o['detector_ms'])}",
            f(o.get("detector_bytes_per_tri", "nan")),
            f"{f(q['ms'])} ({f(q['tri_per_s'])})" if q else "-",
            f"{f(e['ms'])} ({f(e['tri_per_s'])})" if e else "-",
            f"{f(e2['ms'])} ({f(e2['tri_per_s'])})" if e2 else "-",
            f"{f(c['ms'])} ({f(c['tri_per_s'])})" if c else "-",
            f(ratio(e["ms"], o["ms"])) if e else "-", f(ratio(c["ms"], o["ms"])) if c else "-",
        ])
    return rows


def contact_section(out):
    """The "In contact and free" and "Start-up" sections, from contact.csv, startup.csv and contact_run.csv."""
    contact, startup = read(out, "contact.csv"), read(out, "startup.csv")
    if not contact and not startup:
        return []
    crun = {r["key"]: r["value"] for r in read(out, "contact_run.csv")}
    models = []
    for r in contact + startup:
        if r["model"] not in models:
            models.append(r["model"])
    idx = contact_index(contact)
    md = ["## In contact and free\n", contact_preamble(crun, contact), contact_summary(models, idx)]
    md.append(table(["model", "triangles", "in contact", "ours mean / p99 ns", "Embree mean / p99 ns",
                     "Embree/ours mean / p99", "CGAL/ours mean / p99", "free: ours mean / p99 ns",
                     "free: Embree/ours", "free: CGAL/ours"], contact_probe_rows(models, idx)))
    md.append("### Coherent paths\n")
    md.append(
        "A walker slides over the surface at 0.01, 0.1, 0.5 and 2 m/s (the model scaled to 15 cm, 1 kHz), the probe "
        f"offset along the normal by {crun.get('path_amplitude', '2r')} x sin(2 pi {crun.get('path_hz', '2')} Hz t). "
        "`deep`: the share of points where the centre is more than r behind the surface after an inside answer: "
        "the cached stream follows the push there (a contact, a deeper search), the stateless contenders answer "
        "free. `shallow`: the ratio without those points (the same question for everyone). Ratios "
        "mean / p99.\n")
    md.append(cache_summary(models, idx))
    md.append(table(["model", "m/s", "deep", "cache mean / p99 ns", "no cache mean / p99 ns", "Embree mean / p99 ns",
                     "Embree/cache", "Embree/no cache", "shallow: Embree/cache", "shallow: no cache/cache",
                     "CGAL/cache"],
                    contact_path_rows(models, idx)))
    md.append("## Start-up\n")
    md.append(
        "Load or generation excluded. Ours: `ClodBuilder` (placement) + `build(d)` + the grid detector, on up to 4 "
        "threads (2 here); Embree: `rtcCommitScene` alone (build quality high, as the query peer), on 1 and 2 "
        "threads; CGAL: the AABB tree's build and `accelerate_distance_queries` (1 thread). Best of the rounds. "
        "Ratios: the peer's time / ours (below 1 the peer starts faster). `first answer`: placement + `build(d)` + a "
        "hierarchy detector on the same set, what the nodes answer with first (`~quick_start`, the default) while "
        "the grid detector is built in the background.\n")
    md.append(table(["model", "triangles", "spheres", "ours ms", "ns/tri", "tri/s", "placement / build / detector ms",
                     "detector B/tri", "first answer ms (tri/s)", "Embree 1t ms (tri/s)", "Embree 2t ms (tri/s)", "CGAL ms (tri/s)", "Embree/ours",
                     "CGAL/ours"], startup_rows(models, startup)))
    return md


if __name__ == "__main__":
    main()
