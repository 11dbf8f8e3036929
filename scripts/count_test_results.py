#!/usr/bin/env python3
"""Counts test cases in catkin's result folder and prints 'N passed, N failed[, N skipped]'.

catkin_test_results counts each gtest 1.12 case twice, and rostest writes a summary file beside
the gtest's own file, so cases are counted once per (suite, name) over all XML files. Exits 1 when
any case failed, when a test binary produced no result (a crash), or when nothing ran.
"""
import os
import sys
import xml.etree.ElementTree as ET


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "."
    cases = {}
    messages = {}
    broken = []
    for folder, _, files in os.walk(root):
        for name in sorted(files):
            if not name.endswith(".xml"):
                continue
            path = os.path.join(folder, name)
            try:
                tree = ET.parse(path)
            except ET.ParseError as err:
                broken.append("%s: %s" % (path, err))
                continue
            for case in tree.iter("testcase"):
                key = (name.split("-")[0] if name.startswith("rostest-") else "", case.get("classname", ""),
                       case.get("name", ""))
                bad = case.find("failure")
                if bad is None:
                    bad = case.find("error")
                if bad is not None:
                    state = "failed"
                    text = (bad.get("message") or "") + "\n" + (bad.text or "")
                    messages.setdefault(key, []).append("%s: %s" % (name, " | ".join(
                        line.strip() for line in text.splitlines() if line.strip())[:600]))
                elif case.find("skipped") is not None or case.get("status") == "notrun":
                    state = "skipped"
                else:
                    state = "passed"
                # A failure anywhere wins over a pass of the same case.
                if cases.get(key) != "failed":
                    cases[key] = state
    passed = sum(1 for s in cases.values() if s == "passed")
    failed = sum(1 for s in cases.values() if s == "failed")
    skipped = sum(1 for s in cases.values() if s == "skipped")
    for line in broken:
        print("unreadable result:", line, file=sys.stderr)
    for key, state in sorted(cases.items()):
        if state == "failed":
            print("FAILED:", "/".join(k for k in key if k), file=sys.stderr)
            for message in messages.get(key, []):
                print("  ", message, file=sys.stderr)
    failed += len(broken)
    line = "%d passed, %d failed" % (passed, failed)
    if skipped:
        line += ", %d skipped" % skipped
    print(line)
    return 1 if failed or passed == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
