"""The session report asks the engine (issue 35 item 4): alarm spans are the engine's latch, positions
the engine's knowledge after each answer, a move's estimate and start what the engine judged the command
with; none is a model of the report's own. Fed a chunk a line at a time, the report's records are the
analyzer's, and what it asked the engine does not depend on how the bytes were chunked."""

from __future__ import annotations

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.analyzer import Analyzer
from sniffer.report import SessionAggregator
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.conversation import Conversation
from xac1_proto.frames import (
    AlarmAnswer,
    MoveDirect,
    MoveDirectAnswer,
    ReadCurrent,
    ReadCurrentAnswer,
    ReadVersion,
    ReadVersionAnswer,
)

T0 = 1_795_000_000.0
RC, RV = ReadCurrent().to_bytes(), ReadVersion().to_bytes()
AT_1000 = ReadCurrentAnswer(n=0, v=0, a=0, o=0, pos=0x1000).to_bytes()
MOVE = MoveDirect(vel=5, a=3, pos=0x3000)


def aggregate(script: list[tuple[float, str, bytes]]) -> tuple[SessionAggregator, list]:
    """``script`` (time, direction, bytes) through an analyzer and an aggregate fed a chunk at a time."""
    agg, analyzer = SessionAggregator(), Analyzer()
    records = []
    for t, d, data in script:
        records += agg.feed(analyzer, Chunk(T0 + t, d, data))
    tail = analyzer.close()
    for r in tail:
        agg.add(r)
    agg.finish(analyzer.summary())
    return agg, records + tail


def test_a_move_after_an_alarm_to_a_read_starts_where_the_engine_knows_the_axis() -> None:
    """An alarm answering a read (0RV answered 0%%01) moves no axis: the engine still knows the position,
    so the next move is drawn from it, with the engine's estimate (``move_time`` of the command as judged).
    The report's own model forgot the position at every alarm and drew no move."""
    engine = Conversation()
    engine.host_frame(RC, T0, T0)
    engine.device_frame(AT_1000, T0 + 0.01)
    estimate = engine.move_time(MOVE)
    agg, _ = aggregate([(0.0, HOST, RC), (0.01, DEVICE, AT_1000), (1.0, HOST, RV),
                        (1.01, DEVICE, AlarmAnswer(code=1).to_bytes()), (2.0, HOST, b"0%C\r\n"),
                        (2.01, DEVICE, b"0%C00\r\n"), (3.0, HOST, MOVE.to_bytes()),
                        (3.0 + estimate, DEVICE, MoveDirectAnswer(vel=5, a=3, pos=0x3000).to_bytes())])
    [move] = agg.moves.items
    x_cmd, x_est, x_ans, start, end, header = move
    assert (start, end, header) == (0x1000, 0x3000, "0MV")
    assert x_est - x_cmd == pytest.approx(estimate)
    assert [p[1] for p in agg.positions.items] == [0x1000, 0x3000]


def test_an_alarm_span_is_the_engines_latch() -> None:
    """Alarm 08 latches; a normal answer meanwhile is latch-broken and does not end it (the engine holds
    the latch); alarm 08 again is a repeat; the reset answered 0%C00 ends it."""
    alarm = AlarmAnswer(code=8).to_bytes()
    agg, records = aggregate([(0.0, HOST, RV), (0.01, DEVICE, alarm), (1.0, HOST, RV),
                              (1.01, DEVICE, ReadVersionAnswer(version="100").to_bytes()), (2.0, HOST, RV),
                              (2.01, DEVICE, alarm), (3.0, HOST, b"0%C\r\n"), (3.01, DEVICE, b"0%C00\r\n")])
    assert "latch-broken" in {c for r in records for c in r.violations}
    [span] = agg.alarms
    assert (span.code, span.answered, span.repeats, span.reaction) == (8, "0RV", 1, "0RV")
    assert span.ended == "reset (0%C answered)"
    assert span.latched_for is not None and abs(span.latched_for - 3.0) < 1e-6


def test_no_move_from_a_start_the_engine_did_not_know() -> None:
    """A 0RC answering FFFFFF (not homed) draws no position; the move after it starts where the engine does
    not know the axis, so only where its answer put it is drawn, no move line (issue 40 item 8: no position
    drawn before one is known)."""
    unhomed = ReadCurrentAnswer(n=0, v=0, a=0, o=0, pos=0xFFFFFF).to_bytes()
    agg, _ = aggregate([(0.0, HOST, RC), (0.01, DEVICE, unhomed), (1.0, HOST, MOVE.to_bytes()),
                        (9.0, DEVICE, MoveDirectAnswer(vel=5, a=3, pos=0x3000).to_bytes()), (10.0, HOST, RC),
                        (10.01, DEVICE, ReadCurrentAnswer(n=0, v=0, a=0, o=0, pos=0x3000).to_bytes())])
    assert [(p[1], p[2]) for p in agg.positions.items] == [(0x3000, "0MV"), (0x3000, "0RC")]
    assert agg.moves.items == []


# (direction, lines sent in one go): the last host chunk holds two commands, the last device chunk both
# answers, as a tap's read or a socat block may
GROUPS = [(HOST, [RC]), (DEVICE, [AT_1000]), (HOST, [RV]), (DEVICE, [AlarmAnswer(code=1).to_bytes()]),
          (HOST, [RV]), (DEVICE, [AlarmAnswer(code=1).to_bytes()]), (HOST, [b"0%C\r\n"]),
          (DEVICE, [b"0%C00\r\n"]), (HOST, [MOVE.to_bytes()]),
          (DEVICE, [MoveDirectAnswer(vel=5, a=3, pos=0x3000).to_bytes()]), (HOST, [RC, RV]),
          (DEVICE, [ReadCurrentAnswer(n=0, v=0, a=0, o=0, pos=0x3000).to_bytes(),
                    ReadVersionAnswer(version="100").to_bytes()])]


def what_it_asked(agg: SessionAggregator) -> tuple:
    """What the aggregate took from the engine: positions, moves and alarm spans (without record numbers
    and places, which the chunking does not move but the kept records may)."""
    return ([p[1:3] for p in agg.positions.items], [m[3:] for m in agg.moves.items],
            [(a.code, a.answered, a.repeats, a.reaction, a.ended) for a in agg.alarms])


@settings(max_examples=budget(60), deadline=None)
@given(st.lists(st.lists(st.integers(1, 30), max_size=3), min_size=len(GROUPS), max_size=len(GROUPS)))
def test_chunking_changes_neither_the_records_nor_what_the_engine_said(cuts: list[list[int]]) -> None:
    """Each group's bytes cut into chunks anywhere (a chunk may hold two lines, or part of one): the
    aggregate's records are the analyzer's own for those chunks, and the positions, moves and alarm spans
    it took from the engine are those of one line a chunk."""
    one_a_line, _ = aggregate([(k * 0.5, d, line) for k, (d, lines) in enumerate(GROUPS) for line in lines])
    script = []
    for k, ((d, lines), at) in enumerate(zip(GROUPS, cuts, strict=True)):
        data, start = b"".join(lines), 0
        for end in sorted({*at, len(data)}):
            if start < end <= len(data):
                script.append((k * 0.5, d, data[start:end]))
                start = end
    agg, records = aggregate(script)
    plain = Analyzer()
    expected = [r for t, d, data in script for r in plain.feed(Chunk(T0 + t, d, data))] + plain.close()
    assert records == expected
    assert what_it_asked(agg) == what_it_asked(one_a_line)
    assert what_it_asked(agg)[2] == [(1, "0RV", 1, "0RV", "reset (0%C answered)")]
