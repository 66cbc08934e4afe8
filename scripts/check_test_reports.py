#!/usr/bin/env python3
"""Fails the test command where a test report shows a skipped or unregistered test.

    check_test_reports.py [--expect NAMES.txt] [--allow-skips] REPORT.xml [REPORT.xml ...]

Each REPORT is a JUnit XML file (pytest --junitxml, ctest --output-junit). A test case that
was skipped or not run is an error, and with --expect every name listed in NAMES.txt (one per
line, # comments) must appear among the reports' test cases: a test that CMake did not
register because a program was not found is a failure, not a quiet gap. --allow-skips (the
test command passes it when FLUIDCAST_REQUIRE_DATA=0, i.e. the user chose to run without
../shared/data) lists skipped tests without failing."""

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path


def cases(report: Path):
    """(name, problem or None) for each test case of a JUnit report."""
    root = ET.parse(report).getroot()
    for case in root.iter("testcase"):
        name = case.get("name", "?")
        if case.get("classname") and not report.name.startswith("ctest"):
            name = f"{case.get('classname')}::{name}"
        status = case.get("status", "run")
        skipped = case.find("skipped")
        if skipped is not None:
            yield name, f"skipped: {skipped.get('message', '').strip()}"
        elif status not in ("run", "fail"):
            yield name, f"status {status}"
        else:
            yield name, None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--expect", type=Path, help="names that must be among the test cases")
    ap.add_argument("--allow-skips", action="store_true", help="list skips, do not fail")
    ap.add_argument("reports", type=Path, nargs="+")
    a = ap.parse_args()
    seen, problems, skips = set(), [], []
    for r in a.reports:
        if not r.is_file():
            problems.append(f"{r}: no test report (did the tests run?)")
            continue
        for name, problem in cases(r):
            seen.add(name)
            if problem:
                (skips if a.allow_skips else problems).append(f"{r.name}: {name}: {problem}")
    if a.expect:
        lines = a.expect.read_text().splitlines()
        expected = [s.strip() for s in lines if s.strip() and not s.startswith("#")]
        problems += [f"{n}: not registered (expected by {a.expect})" for n in expected
                     if n not in seen]
    for p in skips:
        print(f"SKIPPED (--allow-skips): {p}", file=sys.stderr)
    for p in problems:
        print(f"FAIL: {p}", file=sys.stderr)
    if not problems:
        print(f"test reports: {len(seen)} test cases, {len(skips) or 'none'} skipped"
              + (", every expected test registered" if a.expect else ""))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
