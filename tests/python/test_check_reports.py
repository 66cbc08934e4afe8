"""scripts/check_test_reports.py: a skipped or unregistered test fails the test command."""

import subprocess
import sys

from shared_data import ROOT

CHECK = ROOT / "scripts" / "check_test_reports.py"

PYTEST = """<testsuites><testsuite name="pytest" tests="2">
<testcase classname="tests.a" name="test_one" time="0.1"/>
{extra}
</testsuite></testsuites>"""

CTEST = """<testsuite name="(empty)" tests="2">
<testcase name="vtk_one" classname="vtk_one" time="1" status="run"/>
<testcase name="vtk_two" classname="vtk_two" time="0" status="{status}">{skipped}</testcase>
</testsuite>"""


def check(tmp_path, pytest_extra="", status="run", skipped="", expect=None):
    (tmp_path / "pytest.xml").write_text(PYTEST.format(extra=pytest_extra))
    (tmp_path / "ctest.xml").write_text(CTEST.format(status=status, skipped=skipped))
    args = [sys.executable, str(CHECK), str(tmp_path / "pytest.xml"), str(tmp_path / "ctest.xml")]
    if expect is not None:
        (tmp_path / "expect.txt").write_text("# comment\n" + "\n".join(expect) + "\n")
        args[2:2] = ["--expect", str(tmp_path / "expect.txt")]
    return subprocess.run(args, capture_output=True, text=True)


def test_clean_reports_pass(tmp_path):
    r = check(tmp_path, expect=["vtk_one", "vtk_two"])
    assert r.returncode == 0, r.stderr
    assert "3 test cases, none skipped" in r.stdout


def test_a_skipped_pytest_fails(tmp_path):
    extra = ('<testcase classname="tests.a" name="test_two">'
             '<skipped message="data not present"/></testcase>')
    r = check(tmp_path, pytest_extra=extra)
    assert r.returncode == 1 and "tests.a::test_two: skipped: data not present" in r.stderr


def test_a_ctest_skip_fails(tmp_path):
    r = check(tmp_path, status="notrun", skipped='<skipped message="SKIP_RETURN_CODE=77"/>')
    assert r.returncode == 1 and "vtk_two: skipped" in r.stderr


def test_an_unregistered_ctest_fails(tmp_path):
    r = check(tmp_path, expect=["vtk_one", "vtk_two", "pvpython_wrapped_mapper"])
    assert r.returncode == 1
    assert "pvpython_wrapped_mapper: not registered" in r.stderr


def test_a_missing_report_fails(tmp_path):
    (tmp_path / "pytest.xml").write_text(PYTEST.format(extra=""))
    r = subprocess.run([sys.executable, str(CHECK), str(tmp_path / "pytest.xml"),
                        str(tmp_path / "absent.xml")], capture_output=True, text=True)
    assert r.returncode == 1 and "no test report" in r.stderr


def test_allow_skips_lists_them_without_failing(tmp_path):
    (tmp_path / "ctest.xml").write_text(
        CTEST.format(status="notrun", skipped='<skipped message="77"/>'))
    r = subprocess.run([sys.executable, str(CHECK), "--allow-skips", str(tmp_path / "ctest.xml")],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "SKIPPED (--allow-skips): ctest.xml: vtk_two" in r.stderr
