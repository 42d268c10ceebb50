"""How the fleet reads one device's result (``conformance.fleet.gather``): no process is started.

The child leaves its exit status, its printed output (verdict line, FAIL lines, safety lines, "run
stopped") and a JUnit file; these tests build those by hand and check the verdict, the failed checks,
the firmware, the unit id and the reason a device was not tested.
"""

from __future__ import annotations

from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from conformance.fleet import (
    CONFORMS,
    EXIT,
    INCOMPLETE,
    INTERRUPTED,
    NOT_CONFORM,
    NOT_TESTED,
    Device,
    Target,
    gather,
    read_junit,
)

JUNIT = ("<testsuites><testsuite><properties>{props}</properties>{cases}</testsuite></testsuites>")


def _device(junit: Path, output: str, status: int | None, unit: str | None = None) -> Device:
    d = Device(Target("socket://127.0.0.1:9", "--port", unit), "d", None, junit, None, [])
    d.output += output.encode()
    d.status = status
    return d


def test_read_junit_gives_properties_and_failed_cases_without_the_test_prefix(tmp_path):
    """Suite properties by name; failures and errors as (check, message), ``test_`` dropped; passed and
    skipped cases are not failures."""
    path = tmp_path / "r.xml"
    path.write_text(JUNIT.format(
        props="<property name='firmware' value='210'/><property name='unit-id' value='U7'/>",
        cases="<testcase name='test_crlf[0RV]'><failure message=' no CR '/></testcase>"
              "<testcase name='echo'><error/></testcase><testcase name='test_ok'/>"
              "<testcase name='test_skip'><skipped/></testcase>"))
    props, failed = read_junit(path)
    assert props == {"firmware": "210", "unit-id": "U7"}
    assert failed == [("crlf[0RV]", "no CR"), ("echo", "")]


def test_read_junit_missing_or_broken_file_gives_nothing(tmp_path):
    """A child that died before writing its JUnit file, or wrote half of it, leaves no properties and no
    failed checks (the verdict then comes from its exit status alone)."""
    broken = tmp_path / "broken.xml"
    broken.write_text("<testsuites><testsuite>")
    assert read_junit(tmp_path / "missing.xml") == ({}, [])
    assert read_junit(broken) == ({}, [])


def test_fail_lines_win_over_junit_and_safety_lines_are_kept(tmp_path):
    """Failed checks come from the child's FAIL/ERROR lines when it printed any (JUnit is the fallback);
    every line saying a restore failed is kept for the table."""
    junit = tmp_path / "d.xml"
    junit.write_text(JUNIT.format(props="", cases="<testcase name='test_other'><failure/></testcase>"))
    out = ("FAIL crlf: every answer ends in CR LF\nERROR echo: the device echoes\n"
           "safety NOT RESTORED: point 5\nxac1 conformance: DOES NOT CONFORM: 2 failed (exit status 1)\n")
    d = _device(junit, out, 1)
    gather(d, interrupted=False)
    assert d.verdict == NOT_CONFORM and d.verdict_line == "DOES NOT CONFORM: 2 failed"
    assert d.failed == [("crlf", "every answer ends in CR LF"), ("echo", "the device echoes")]
    assert d.safety == ["safety NOT RESTORED: point 5"]


def test_unit_id_from_the_ports_file_first_then_junit_then_usb_serial(tmp_path):
    """The unit id the ports file gives wins; else the JUnit property; else what the fleet found
    before the run (the USB serial number)."""
    junit = tmp_path / "d.xml"
    junit.write_text(JUNIT.format(props="<property name='unit_id' value='FROM-JUNIT'/>", cases=""))
    named = _device(junit, "", 0, unit="FROM-FILE")
    gather(named, interrupted=False)
    from_junit = _device(junit, "", 0)
    from_junit.unit = "USB123"
    gather(from_junit, interrupted=False)
    usb = _device(tmp_path / "none.xml", "", 0)
    usb.unit = "USB123"
    gather(usb, interrupted=False)
    assert (named.unit, from_junit.unit, usb.unit) == ("FROM-FILE", "FROM-JUNIT", "USB123")


def test_exit_statuses_read_as_verdicts(tmp_path):
    """0 conforms, 4 is incomplete, 2 is an interrupt only when the fleet was interrupted (else the
    device was not tested), and exit 1 without a verdict line is a crash, not a defect."""
    none = tmp_path / "none.xml"
    cases = [(0, "", False, CONFORMS), (4, "", False, INCOMPLETE), (2, "", True, INTERRUPTED),
             (2, "", False, NOT_TESTED), (1, "", False, NOT_TESTED),
             (1, "xac1 conformance: DOES NOT CONFORM: x (exit status 1)\n", False, NOT_CONFORM),
             (3, "", False, NOT_TESTED)]
    seen = []
    for status, out, interrupted, _ in cases:
        d = _device(none, out, status)
        gather(d, interrupted)
        seen.append(d.verdict)
    assert seen == [want for *_, want in cases]


def test_killed_after_the_grace_is_not_tested_and_may_be_unrestored(tmp_path):
    """A child killed because it did not stop in time is NOT TESTED, whatever its status, and the reason
    says its device may not be restored (led by the verdict line's head when it printed one)."""
    d = _device(tmp_path / "none.xml", "run stopped: interrupted\n"
                "xac1 conformance: INTERRUPTED: stopping (exit status 2)\n", -9)
    d.killed = True
    gather(d, interrupted=True)
    assert d.verdict == NOT_TESTED
    assert d.reason.startswith("INTERRUPTED: did not stop within ") and "may not be restored" in d.reason


def test_not_tested_reason_names_the_verdict_once(tmp_path):
    """The child's own verdict head leads the reason, and is not repeated when its reason already starts
    with it."""
    out = ("run stopped: NO ANSWER: nothing came back\n"
           "xac1 conformance: NO ANSWER: on socket://x (exit status 3)\n")
    d = _device(tmp_path / "none.xml", out, 3)
    gather(d, interrupted=False)
    assert d.reason == "NO ANSWER: nothing came back"
    plain = _device(tmp_path / "none.xml", "xac1 conformance: NO ANSWER: on x (exit status 3)\n", 3)
    gather(plain, interrupted=False)
    assert plain.reason == "NO ANSWER (exit status 3)"


@given(output=st.lists(st.sampled_from([
           "FAIL crlf: no CR", "ERROR echo: boom", "safety PROBLEM at point 3", "run stopped: gone",
           "xac1 conformance: DOES NOT CONFORM: 1 failed (exit status 1)",
           "xac1 conformance: NOT TESTED: no device (exit status 3)", "device 123 on x",
           "   firmware version: 9.9", "", "noise: with a colon"]) | st.text(max_size=30), max_size=8),
       status=st.none() | st.integers(-15, 6), interrupted=st.booleans(), killed=st.booleans())
def test_any_output_and_status_give_a_verdict_and_an_untested_device_a_reason(
        output, status, interrupted, killed):
    """Whatever the child printed and however it ended, gather gives one of the fleet's verdicts; a
    device not tested always has a reason, and 0 is CONFORMS unless the child was killed."""
    d = Device(Target("socket://127.0.0.1:9", "--port"), "d", None, Path("/nonexistent/d.xml"), None, [])
    d.output += "\n".join(output).encode()
    d.status, d.killed = status, killed
    gather(d, interrupted)
    assert d.verdict in EXIT
    if d.verdict == NOT_TESTED:
        assert d.reason
    assert (d.verdict == CONFORMS) == (status == 0 and not killed)
