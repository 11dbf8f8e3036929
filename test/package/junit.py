"""Writes one JUnit result file (the format catkin's run_tests and scripts/count_test_results.py read)."""
import os
from xml.sax.saxutils import escape, quoteattr


def write_result(path, suite, cases):
    """cases: list of (name, failure text or None). Creates the folder of path."""
    failures = sum(1 for _, failure in cases if failure)
    lines = ['<?xml version="1.0" encoding="utf-8"?>',
             '<testsuite name=%s tests="%d" failures="%d" errors="0">' % (quoteattr(suite), len(cases), failures)]
    for name, failure in cases:
        lines.append('  <testcase classname=%s name=%s>' % (quoteattr(suite), quoteattr(name)))
        if failure:
            lines.append('    <failure message=%s>%s</failure>' % (quoteattr(failure.splitlines()[0][:200]),
                                                                    escape(failure)))
        lines.append('  </testcase>')
    lines.append('</testsuite>')
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as out:
        out.write("\n".join(lines) + "\n")
