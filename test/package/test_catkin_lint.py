#!/usr/bin/env python3
"""catkin_lint at its strictest level (-W2: errors, warnings and notices) finds nothing in the package.

Usage: test_catkin_lint.py PACKAGE_DIR RESULT_XML. PACKAGE_DIR is the repository itself, not a workspace's
folder of links to it (catkin_lint does not follow links into folders: it would miss the scripts). The one
notice left out is package_path_name: the clone's folder name is its owner's choice. Every finding fails the case and is listed in its message;
a finding the package accepts is silenced where it arises, by a `#catkin_lint: ignore_once ID` pragma with
its reason beside it in CMakeLists.txt (the README lists them). Exit 0 when the result file was written.
"""
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from junit import write_result  # noqa: E402


def lint(package_dir):
    """Returns the failure text, or None when catkin_lint reports nothing."""
    try:
        run = subprocess.run(["catkin_lint", "-W2", "--strict", "-q", "--ignore", "package_path_name", package_dir],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True, timeout=300)
    except FileNotFoundError:
        return "catkin_lint is not installed (Debian: apt-get install catkin-lint; `make deps` does it)"
    findings = [line for line in run.stdout.splitlines()
                if ": error:" in line or ": warning:" in line or ": notice:" in line]
    if run.returncode != 0 or findings:
        return "catkin_lint -W2 found %d problem(s) (exit %d):\n%s" % (len(findings), run.returncode, run.stdout)
    return None


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    failure = lint(sys.argv[1])
    write_result(sys.argv[2], "package", [("catkin_lint_W2_clean", failure)])
    print(failure or "catkin_lint -W2: no problems")
    return 0


if __name__ == "__main__":
    sys.exit(main())
