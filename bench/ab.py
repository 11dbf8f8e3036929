#!/usr/bin/env python3
"""Compares two builds of a timing tool by alternating them: A, B, then B, A, and so on.

    python3 bench/ab.py [--rounds N] OLD_BINARY NEW_BINARY -- ARGUMENTS...

Both binaries get the same arguments and must print lines of the form
    NAME PASS n=COUNT mean X p50 X p90 X p99 X max X ...
(bench/proxy_ticks.cpp). This machine's load moves a whole run by tens of percent within minutes, so two runs taken
at different times compare nothing; alternating runs see the same load. Prints, per line name and statistic, the
median over the rounds for each build, their ratio (B / A, below 1: B is faster) and each build's minimum.
"""
import argparse
import collections
import re
import statistics
import subprocess
import sys

LINE = re.compile(r'^(\S+)\s+(\S+)\s+n=\d+\s+mean\s+([\d.]+)\s+p50\s+([\d.]+)\s+p90\s+([\d.]+)\s+p99\s+([\d.]+)'
                  r'\s+max\s+([\d.]+)')
STATS = ('mean', 'p50', 'p90', 'p99', 'max')


def run(binary, arguments):
    out = subprocess.run([binary] + arguments, capture_output=True, text=True, check=True).stdout
    rows = {}
    for line in out.splitlines():
        m = LINE.match(line)
        if m:
            rows[m.group(1) + ' ' + m.group(2)] = dict(zip(STATS, map(float, m.groups()[2:])))
    return rows


def main():
    if '--' not in sys.argv:
        sys.exit(__doc__)
    split = sys.argv.index('--')
    parser = argparse.ArgumentParser()
    parser.add_argument('--rounds', type=int, default=8)
    parser.add_argument('old')
    parser.add_argument('new')
    options = parser.parse_args(sys.argv[1:split])
    arguments = sys.argv[split + 1:]
    if options.old == options.new:
        sys.exit('ab.py: give two different binaries (copy one build elsewhere first)')
    seen = {options.old: collections.defaultdict(list), options.new: collections.defaultdict(list)}
    for i in range(options.rounds):
        for binary in (options.old, options.new) if i % 2 == 0 else (options.new, options.old):
            for key, row in run(binary, arguments).items():
                for stat in STATS:
                    seen[binary][(key, stat)].append(row[stat])
    print(f'{options.rounds} rounds, alternating; A = {options.old}, B = {options.new}')
    for key in seen[options.old]:
        a, b = seen[options.old][key], seen[options.new].get(key)
        if not b:
            continue
        ma, mb = statistics.median(a), statistics.median(b)
        print(f'{key[0]:16s} {key[1]:5s} A {ma:9.0f}  B {mb:9.0f}  B/A {mb / ma:6.3f}   min A {min(a):9.0f}  B {min(b):9.0f}')


if __name__ == '__main__':
    main()
