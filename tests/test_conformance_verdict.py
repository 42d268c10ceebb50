"""The verdict rules of ``conformance.report.Report``, over every mix of outcomes (hypothesis): CONFORMS
only when every check of a stated rule that can run over the line ran and passed; INCOMPLETE (exit 4,
0 with --allow-incomplete) when nothing failed but checks were not run; an interruption is exit 2; a
failure is exit 1; a run that could not go on is exit 3. The report files render every such mix."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from hypothesis import given
from hypothesis import strategies as st

from conformance.junit import junit_tree
from conformance.report import Report, html_page, markdown
from conformance.results import ERROR, FAIL, MANUAL, PASS, SKIP, Result

VERDICTS = st.sampled_from([PASS, PASS, PASS, FAIL, ERROR, SKIP, MANUAL])


def result(i: int, verdict: str, info: bool = False) -> Result:
    message = {SKIP: "moves the actuator: pass --allow-motion --safe-range LO:HI",
               MANUAL: "press the emergency stop; expect: 0%%0E", FAIL: "0RV: expected <x>, received '0' LF"}
    return Result(f"checks/test_t{i % 3}.py::test_c{i}", f"c{i}", f"t{i % 3}", f"rule {i} <&>", "Frames",
                  info, verdict, message.get(verdict, ""))


@st.composite
def reports(draw: st.DrawFn) -> Report:
    verdicts = draw(st.lists(VERDICTS, max_size=12))
    return Report(port="socket://127.0.0.1:1", version="100", date="2026-01-01 00:00:00 UTC",
                  options=[("port", "x")], checks=[result(i, v) for i, v in enumerate(verdicts)], infos=[],
                  info_errors=[], timing=[], safety=[], safety_problems=[], abort=None,
                  not_run=draw(st.integers(0, 3)), deselected=draw(st.integers(0, 3)),
                  interrupted=draw(st.sampled_from([None, "SIGTERM"])), command_line="xac1 conformance")


@given(reports(), st.booleans())
def test_verdict_and_exit_status(rep: Report, allow_incomplete: bool) -> None:
    """One head word and one exit status for each mix of outcomes, as docs/conformance.md's table says."""
    failed = any(r.verdict in (FAIL, ERROR) for r in rep.checks)
    missing = sum(r.verdict == SKIP for r in rep.checks) + rep.not_run + rep.deselected
    passed = sum(r.verdict == PASS for r in rep.checks)
    status = rep.exit_status(allow_incomplete)
    if rep.interrupted:
        assert status == 2 and "interrupted by SIGTERM" in rep.verdict_line
        if rep.head == "INCOMPLETE":  # checks -k left out are told apart from those the interrupt cut
            assert rep.verdict_line.startswith(f"INCOMPLETE: {missing} of {rep.total} checks not run")
            assert (f"{rep.deselected} of them left out with -k" in rep.verdict_line) == bool(rep.deselected)
    elif failed:
        assert rep.head == "DOES NOT CONFORM" and status == 1
    elif missing or not passed:
        assert rep.head == "INCOMPLETE" and status == (0 if allow_incomplete else 4)
        if missing:
            assert rep.verdict_line.startswith(f"INCOMPLETE: {missing} of {rep.total} checks not run")
    else:
        assert rep.head == "CONFORMS" and status == 0
    assert rep.accepted == (rep.head == "CONFORMS")
    assert (rep.head == "CONFORMS") <= (not failed and not missing and not rep.interrupted and passed > 0)


@given(reports())
def test_every_mix_renders(rep: Report) -> None:
    """The HTML is escaped, the Markdown and JUnit carry the verdict; JUnit tests are the stated-rule
    checks (manual steps as skipped), never information."""
    page = re.sub(r"<script>.*?</script>", "", html_page(rep), count=1, flags=re.S)  # plotly.js itself
    assert "<&>" not in page and (not rep.checks or "rule 0 &lt;&amp;&gt;" in page)
    assert rep.verdict_line in markdown(rep)
    suite = junit_tree(rep).getroot().find("testsuite")
    assert suite is not None
    cases = suite.findall("testcase")
    assert int(suite.get("tests", "-1")) == len(cases) == len(rep.checks) + len(rep.not_run_checks)
    failures = [c for c in cases if c.find("failure") is not None]
    assert len(failures) == sum(r.verdict == FAIL for r in rep.checks)
    ET.tostring(suite)  # serialisable
