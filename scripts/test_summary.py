#!/usr/bin/python3
"""Counts test cases in JUnit XML result files (gtest and rostest).

usage: scripts/test_summary.py RESULTS_DIR
Prints every failed or erroneous test case (with the first lines of its message), then "N passed, N failed[, N skipped]".
Exit status 1 when any test failed or no result was found.
(catkin_test_results counts gtest's nested <testsuites> twice, hence this script.)
"""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def main():
    results = sys.argv[1]
    passed = failed = skipped = 0
    files = sorted(glob.glob(os.path.join(results, "**", "*.xml"), recursive=True))
    for path in files:
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as e:
            print(f"{path}: unreadable result file ({e})")
            failed += 1
            continue
        cases = list(root.iter("testcase"))
        if not cases:
            print(f"{path}: no test cases (the test binary did not run)")
            failed += 1
        for case in cases:
            name = f"{case.get('classname', '')}.{case.get('name', '')}"
            bad = case.find("failure") if case.find("failure") is not None else case.find("error")
            if bad is not None:
                failed += 1
                msg = (bad.get("message") or bad.text or "").strip().splitlines()
                print(f"FAILED {os.path.basename(path)}: {name}" + (f": {msg[0]}" if msg else ""))
                # The rest of the message (expected, actual, the test's own words) says what went wrong
                # where only this summary is kept, as in CI's log.
                for more in msg[1:8]:
                    print(f"    {more}")
            elif case.find("skipped") is not None or case.get("status") == "notrun":
                skipped += 1
            else:
                passed += 1
    if not files:
        print(f"no test results in {results}")
        failed += 1
    line = f"{passed} passed, {failed} failed"
    if skipped:
        line += f", {skipped} skipped"
    print(line)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
