"""A restore that failed, or that a dead port left undone, is in the verdict line (what it was) and in
the fleet table, not only in the safety section (issue 23 item 9)."""

from __future__ import annotations

import io
from pathlib import Path

from hypothesis import given
from rich.console import Console
from test_conformance_verdict import reports
from test_fleet import _device

from conformance.fleet import gather
from conformance.report import Report


def _report(**kw) -> Report:
    fields = {"safety_problems": [], "abort": None, **kw}
    return Report(port="socket://127.0.0.1:1", version="100", date="2026-01-01 00:00:00 UTC",
                  options=[("port", "x")], checks=[], infos=[], info_errors=[], timing=[], safety=[],
                  command_line="xac1 conformance", **fields)


def test_a_failed_restore_is_in_the_verdict_line():
    """A device that ignores the point writes of the restore: DOES NOT CONFORM, exit 1, and the verdict
    line says the restore failed and what (docs/protocol.md: the suite leaves a device as it found it)."""
    rep = _report(safety_problems=["point 3: wrote back V=5 A=2 O=1 Pos=000400 but it reads V=0 A=0 O=0 "
                                   "Pos=000000"], restore_failed=["point 3"])
    assert rep.head == "DOES NOT CONFORM" and rep.exit_status() == 1
    assert rep.verdict_line.endswith("; THE RESTORE FAILED (point 3; see the safety section)")


def test_a_restore_a_dead_port_left_undone_names_what_is_not_verified():
    """The port died: THE DEVICE STOPPED ANSWERING, exit 3, and the verdict line names what the run
    changed that could not be restored or verified."""
    rep = _report(stopped=True, abort="the port failed",
                  safety_unverified=["the restore could not be done or verified: the port failed",
                                     "not verified: point 3, written during the run; ..."],
                  restore_unverified=["point 3", "the OUT ports"])
    assert rep.exit_status() == 3
    assert rep.verdict_line.startswith("THE DEVICE STOPPED ANSWERING: the run did not complete")
    assert rep.verdict_line.endswith("; THE DEVICE COULD NOT BE RESTORED (not verified: point 3, the OUT "
                                     "ports; see the safety section)")


@given(reports())
def test_every_mix_with_a_failed_restore_says_so(rep: Report):
    """Whatever the checks gave, a failed restore makes the verdict DOES NOT CONFORM (or interrupted)
    and the verdict line says the restore failed."""
    rep.safety_problems = ["OUT ports: wrote back 0 but they read 3"]
    rep.restore_failed = ["the OUT ports"]
    assert "THE RESTORE FAILED (the OUT ports; see the safety section)" in rep.verdict_line
    assert rep.exit_status() in (1, 2)


def test_the_fleet_table_says_the_restore_failed(tmp_path: Path):
    """A child whose restore failed, or was left undone: the fleet table's verdict cell says so."""
    from conformance.fleet import fleet_table

    failed = _device(tmp_path, "safety PROBLEM: point 3: wrote back V=5 but it reads V=0\nxac1 conformance: "
                     "DOES NOT CONFORM: 98 passed, 0 failed (of 98 checks of stated rules); THE RESTORE "
                     "FAILED (point 3; see the safety section) (exit status 1)\n", 1)
    gather(failed, interrupted=False)
    undone = _device(tmp_path, "safety NOT RESTORED: not verified: point 3\nxac1 conformance: THE DEVICE "
                     "STOPPED ANSWERING: the run did not complete (...) (exit status 3)\n", 3)
    gather(undone, interrupted=False)
    out = io.StringIO()
    Console(file=out, width=300, color_system=None).print(fleet_table([failed, undone]))
    rows = [line for line in out.getvalue().splitlines() if "socket://" in line]
    assert "DOES NOT CONFORM (RESTORE FAILED)" in rows[0] and "NOT TESTED (NOT RESTORED)" in rows[1]
