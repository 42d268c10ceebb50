"""Parts of the conformance kit read in-process (no device, no pytest run): the fleet's progress pipe
(``conformance.fleet_progress``), the live progress lines (``conformance.progress``), and the malformed
commands and offsets the checks send (``conformance.kit``)."""

from __future__ import annotations

import io
import json
import os
from types import SimpleNamespace

from hypothesis import given
from hypothesis import strategies as st
from rich.console import Console
from strategies import frames_of

from conformance import fleet_progress, kit
from conformance.fleet import Device, Target
from conformance.progress import Progress
from xac1_proto import codec, spec


def test_fleet_progress_tells_the_pipe_what_the_fleet_shows(monkeypatch):
    """The plugin writes ``{"of": N}``, then ``{"check": NAME, "n": K}`` per check, then a state, one JSON
    object a line to the fd the fleet names; the fleet's ``Device.progress`` reads them back into its
    live line."""
    read_fd, write_fd = os.pipe()
    monkeypatch.setenv(fleet_progress.ENV, str(write_fd))
    fleet_progress.pytest_collection_finish(SimpleNamespace(items=[1, 2, 3]))  # type: ignore[arg-type]
    fleet_progress.pytest_runtest_logstart("conformance/checks/test_alarms.py::test_alarm_latched[0WP]", None)
    os.close(write_fd)
    with os.fdopen(read_fd, "rb") as pipe:
        data = pipe.read()
    assert [json.loads(line) for line in data.splitlines()] == [
        {"of": 3}, {"check": "alarm_latched[0WP]", "n": 1}]
    d = Device(Target("socket://127.0.0.1:9", "--port"), "d", None, None, None, [])  # type: ignore[arg-type]
    d.progress(data[:7])  # a line cut between two reads is kept for the next
    d.progress(data[7:])
    assert (d.of, d.n, d.state_text()) == (3, 1, "check 1/3: alarm_latched[0WP]")


def test_fleet_progress_without_the_variable_does_nothing(monkeypatch):
    """Run alone (no fleet), the plugin writes nothing anywhere and never fails the run: with no fd named,
    or a name that is no fd, nothing reaches the pipe it would otherwise write to."""
    read_fd, write_fd = os.pipe()
    session = SimpleNamespace(items=[1, 2])
    try:
        monkeypatch.delenv(fleet_progress.ENV, raising=False)
        fleet_progress.pytest_collection_finish(session)  # type: ignore[arg-type]
        monkeypatch.setenv(fleet_progress.ENV, "not-a-number")
        fleet_progress.pytest_collection_finish(session)  # type: ignore[arg-type]
        monkeypatch.setenv(fleet_progress.ENV, str(write_fd))  # the one told line, proving the pipe works
        fleet_progress.pytest_collection_finish(session)  # type: ignore[arg-type]
    finally:
        os.close(write_fd)
    with os.fdopen(read_fd, "rb") as pipe:
        assert pipe.read() == b'{"of": 2}\n'


def test_progress_off_a_terminal_prints_a_line_per_rule_group():
    """In a log (not a terminal): one line as each rule group starts, with the check's number; the final
    lines are printed whole."""
    out = io.StringIO()
    p = Progress(Console(file=out, force_terminal=False, width=60, highlight=False))
    p.begin(3)
    for topic, name in (("framing", "crlf"), ("framing", "length"), ("alarms", "latched")):
        p.check(topic, name)
        p.finished_one()
    p.lines([("xac1 conformance: CONFORMS: 3 passed, 0 failed (of 3 checks of stated rules)", "good")])
    p.stop()
    lines = out.getvalue().splitlines()
    groups = [line.split("] ", 1)[1] for line in lines[:2]]
    assert groups == ["framing (check 1 of 3)", "alarms (check 3 of 3)"]
    assert lines[-1].startswith("xac1 conformance: CONFORMS")


def test_malformed_commands_are_each_broken_one_way():
    """Every malformed command of the kit ends in LF and the lenient decoder finds it faulty (a check
    that sends it expects an alarm answer)."""
    fake = SimpleNamespace(point=lambda k=0: 1 + k, safe_pos=lambda k=0: 0x100, other_target=lambda: 0x200)
    for m in kit.MALFORMED:
        raw = m.make(fake)  # type: ignore[arg-type]
        assert raw.endswith(b"\n"), m.name
        frame, violations = codec.diagnose(raw, spec.COMMAND)
        assert violations, f"{m.name}: {raw!r} reads as a valid command"


@given(st.sampled_from(kit.TWO_ANSWERS).flatmap(lambda h: frames_of((h, spec.ANSWER))))
def test_two_offset_points_at_the_mandatory_2(answer):
    """``kit.two_offset(header)`` (where the checks look for, or break, the mandatory 2) is the offset
    of the 2 in every answer of that header."""
    assert answer.to_bytes()[kit.two_offset(answer.header)] == ord("2")
