#!/usr/bin/env bash
# Checksums of what the core produces: the sphere sets clod_tool builds (three clusterings, three distances)
# and the answers it gives (three modes, three fast levels) on fixed probes, on the meshes in ../shared/data.
# A refactor that must not change results prints the same lines before and after; the timings are not in them.
# Usage: bash bench/checksums.sh [path/to/clod_tool]   (default: the one `make build` made)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
tool=${1:-$here/.build/ws/devel/lib/clod_haptics/clod_tool}
meshes=$here/../shared/data/meshes
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$work/probes.csv" <<'PY'
import random, sys
rng = random.Random(20261124)
with open(sys.argv[1], "w") as f:
    f.write("x,y,z\n")
    for _ in range(20000):
        f.write("%.17g,%.17g,%.17g\n" % tuple(rng.uniform(-0.55, 0.55) for _ in range(3)))
PY
sum() { grep -v '^stats:' "$1" | sha256sum | cut -c1-16; }  # the stats line holds timings
for mesh in mesh_with_border.off elephant.off mannequin-devil.off head.off; do
  for clustering in single-link cube tight; do
    for d in 0 0.02 0.08; do
      "$tool" build --mesh "$meshes/$mesh" --normalize --distance "$d" --clustering "$clustering" \
        --out "$work/set.yaml" > /dev/null
      echo "$mesh build $clustering d=$d $(sum "$work/set.yaml")"
    done
  done
  for mode in exact paper spheres; do
    for fast in grid hierarchy flat; do
      "$tool" query --mesh "$meshes/$mesh" --normalize --distance 0.02 --radius 0.01 --mode "$mode" --fast "$fast" \
        --probes "$work/probes.csv" --out "$work/answers.csv" > /dev/null
      echo "$mesh query $mode $fast $(sum "$work/answers.csv")"
    done
  done
done
