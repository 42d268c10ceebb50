"""The replay loop (``sniffer.replay_player``) on real pyserial ports to the built-in simulator: a
deterministic device replayed gives the same answers, the captured gaps are kept, back-to-back lines stay
back to back, and refused lines are not sent (docs/replay.md "What is sent, and when")."""

from __future__ import annotations

import time

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

from sniffer.analyzer import Analyzer
from sniffer.replay_player import FAST, Player
from sniffer.replay_script import script_of
from xac1_proto import spec
from xac1_proto.chunk import Chunk
from xac1_proto.client import open_port
from xac1_proto.replay import Script

SIM = "xac1sim://?time_scale=0"
MALFORMED = [b"0RP\r\n", b"ORV\r\n", b"0rs\r\n", b"0XX\r\n", b"0WS1\r\n"]


def captured(lines: list[bytes], gaps: list[float] | None = None) -> Script:
    """A capture made here: each line sent to a fresh simulator and its answer read, both with times."""
    port, _ = open_port(SIM)
    chunks = []
    try:
        for n, line in enumerate(lines):
            if gaps:
                time.sleep(gaps[n])
            chunks.append(Chunk(time.time(), "host", line))
            port.write(line)
            answer = port.read_until(b"\n")
            if answer:
                chunks.append(Chunk(time.time(), "device", answer))
    finally:
        port.close()
    analyzer = Analyzer(no_answer_timeout=0.2)
    return script_of([r for c in chunks for r in analyzer.feed(c)] + analyzer.close())


def play(script: Script, url: str = SIM, **kwargs) -> list:
    port, _ = open_port(url)
    try:
        return Player(port, script, Analyzer(no_answer_timeout=0.2), **kwargs).run()
    finally:
        port.close()


@settings(max_examples=budget(12), deadline=None)
@given(st.lists(st.one_of(frames(spec.COMMAND).map(lambda f: f.to_bytes()), st.sampled_from(MALFORMED)),
                min_size=1, max_size=8))
def test_a_deterministic_device_replayed_answers_the_same(lines):
    """Any sequence of commands (malformed ones too) captured from a fresh simulator and replayed
    against another fresh one: every answer the same, each line sent once, in order."""
    script = captured(lines)
    results = play(script, pace=FAST)
    assert [r.line.raw for r in results] == lines
    assert [(r.line.raw, r.comparison.differences) for r in results if not r.same] == []


def test_captured_gaps_are_kept():
    """At the captured pace, a line sent a while after the previous answer goes the same while after
    the answer now (not sooner); ``fast`` does not wait."""
    script = captured([b"0RV\r\n", b"0RS\r\n", b"0RV\r\n"], gaps=[0.0, 0.3, 0.0])
    assert script.lines[1].after_answer and script.lines[1].gap_s >= 0.3
    slow = play(script)
    assert slow[1].t_sent - slow[0].t_sent >= 0.3
    fast = play(script, pace=FAST)
    assert fast[1].t_sent - fast[0].t_sent < 0.2


def test_back_to_back_lines_stay_back_to_back():
    """Two lines the capture shows sent before the first one's answer came are sent back to back again:
    against a device as slow as the captured one (50 ms turnaround), the new conversation has the
    overlap (``overlapping-command``) on the second."""
    from xac1_proto.replay import Answer, ScriptBuilder

    builder = ScriptBuilder()
    builder.host(0, b"0RV\r\n", 1.0, 1.005)
    builder.host(1, b"0RS\r\n", 1.006, 1.011)
    builder.device(Answer(b"0RV100\r\n", None, None, 1.02, 1.027), 0)
    builder.device(Answer(b"0RS02\r\n", None, None, 1.03, 1.036), 1)
    results = play(builder.build(), "xac1sim://?time_scale=1&turnaround=50")
    assert "overlapping-command" in results[1].violations
    assert results[1].t_sent - results[0].t_sent < 0.05


@pytest.mark.parametrize("pace", ["captured", FAST])
def test_a_refused_line_is_not_sent(pace, monkeypatch):
    """A line the guard refuses is marked skipped with the reason and never written to the port."""
    script = captured([b"0RV\r\n", b"0MP0\r\n", b"0RV\r\n"])
    written = []
    port, _ = open_port(SIM)
    real_write = port.write
    try:
        def write(data: bytes) -> int:
            written.append(bytes(data))
            return real_write(data)

        monkeypatch.setattr(port, "write", write)  # the port's own write, wrapped to see what is sent
        results = Player(port, script, pace=pace,
                         check=lambda raw: "no moves here" if raw.startswith(b"0MP") else None).run()
    finally:
        port.close()
    assert [r.skipped for r in results] == [None, "no moves here", None]
    assert written == [b"0RV\r\n", b"0RV\r\n"]


def test_each_result_comes_as_soon_as_it_is_final():
    """A line's result is handed out once nothing can change it (before the next line goes, when nothing
    is owed), not at the end of the replay: compared, in order."""
    script = captured([b"0RV\r\n", b"0RS\r\n", b"0RV\r\n"], gaps=[0.0, 0.2, 0.2])
    seen: list[tuple[int, float, bool]] = []
    port, _ = open_port(SIM)
    try:
        player = Player(port, script, Analyzer(no_answer_timeout=0.2),
                        on_result=lambda r: seen.append((r.line.n, time.monotonic(), r.same)))
        results = player.run()
    finally:
        port.close()
    assert [n for n, _, _ in seen] == [0, 1, 2] and all(same for _, _, same in seen)
    assert seen[0][1] <= results[1].t_sent + 0.01 and seen[1][1] <= results[2].t_sent + 0.01
