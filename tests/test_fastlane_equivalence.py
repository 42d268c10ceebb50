"""The analyzer's fast lane (``sniffer/fastlane.py``, ``Analyzer(fast=True)``) changes nothing: every call
returns the records the full path returns (``Analyzer(fast=False)``), field by field and as JSON lines,
the summary is the same at every step, and so are the analyzer's answers (``waiting``,
``expecting_answer``, ``bytes_in``).

The conversations repeat a few clean exchanges many times (so the memo fills and hits), with anomalies
mixed in that must invalidate it or make it replay a held command: a changed read-back value, an alarm
answer, a missing answer, junk, split chunks, line errors, letter O, a move, an alarm reset, answers
around the 1 s answer window and the 1 s device idle flush, chunks without time in a timed capture, ticks
and questions between a command and its answer, and the end of the data with and without a time.
The generated conversations of tests/test_decode_equivalence.py and its corpus are compared too.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from typing import Any
from unittest import mock

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_decode_equivalence import (
    _reference_tally_add,
    chunks_of,
    corpus_cases,
    cuts,
    events,
    gaps,
    line_error_at,
    read_corpus_case,
)

from sniffer import fastlane
from sniffer.analyzer import Analyzer
from sniffer.records import FrameRecord, Record
from xac1_proto import frames as fr
from xac1_proto.chunk import DEVICE, HOST, Chunk

T0 = 1_790_000_000.0

# (command, its answer, an answer that breaks a rule: a changed read-back value or echo)
PAIRS: list[tuple[bytes, bytes, bytes]] = [
    (c.to_bytes(), a.to_bytes(), b.to_bytes()) for c, a, b in [
        (fr.ReadVersion(), fr.ReadVersionAnswer(version="100"), fr.ReadVersionAnswer(version="101")),
        (fr.ReadPoint(n=3), fr.ReadPointAnswer(n=3, v=9, a=3, o=0, pos=0x12345),
         fr.ReadPointAnswer(n=3, v=9, a=3, o=0, pos=0x12346)),
        (fr.WritePoint(n=3, v=9, a=3, o=0, pos=0x12345), fr.WritePointAnswer(n=3, v=9, a=3, o=0, pos=0x12345),
         fr.WritePointAnswer(n=3, v=8, a=3, o=0, pos=0x12345)),
        (fr.ReadOutputs(), fr.ReadOutputsAnswer(o=2), fr.ReadOutputsAnswer(o=3)),
        (fr.WriteOutputs(o=2), fr.WriteOutputsAnswer(o=2), fr.WriteOutputsAnswer(o=3)),
        (fr.SwitchMode(mode=1), fr.SwitchModeAnswer(mode=1), fr.SwitchModeAnswer(mode=0)),
        (fr.AlarmReset(), fr.AlarmResetAnswer(), fr.AlarmAnswer(code=0x0E)),
    ]]
MOVE = (b"0MV3C3001000\r\n", b"0MV3C3001000\r\n")
ALARMS = [fr.AlarmAnswer(code=code).to_bytes() for code in (0x01, 0x08, 0x0E, 0x0E)]  # 0E: a latched stop
JUNK = [b"\x01\x02\r\n", b"0R", b"\r\n", b"0RV1", b"\xff"]
# answer delays around the 1 s window and the 1 s idle flush, gaps between exchanges
LATENCIES = [0.001, 0.0025, 0.5, 0.999999, 1.0, 1.000001, 1.5, 3.0]
GAPS = [0.0, 0.001, 0.5, 0.999999, 1.0, 1.000001, 2.0]

ANOMALIES = ["readback", "alarm", "silent", "letter_o", "lower", "no_cr", "split_host", "split_device",
             "error_host", "error_device", "junk_host", "junk_device", "untimed_command", "untimed_answer",
             "tick", "tick_late", "ask", "move", "overlap", "unsolicited", "late", "backwards", "host_lf",
             "answer_and_more"]
clean = st.tuples(st.just("clean"), st.integers(0, 2))  # the first pairs repeat most
quick = st.sampled_from(LATENCIES[:3])
step = st.tuples(
    st.one_of(clean, clean, clean, clean, clean, st.tuples(st.just("clean"), st.integers(0, len(PAIRS) - 1)),
              st.tuples(st.sampled_from(ANOMALIES), st.integers(0, len(PAIRS) - 1))),
    st.one_of(st.sampled_from(GAPS), st.floats(0, 1.5)),
    st.one_of(quick, quick, quick, st.sampled_from(LATENCIES), st.floats(0, 1.2)),
    st.integers(0, 20))
steps = st.lists(step, min_size=4, max_size=80)

Op = tuple[str, Any]


def ops_of(items: list[tuple[tuple[str, int], float, float, int]], timed: bool) -> list[Op]:
    """The conversation as calls: ("feed", Chunk), ("tick", now), ("ask", None)."""
    ops: list[Op] = []
    t = T0

    def chunk(who: str, data: bytes, when: float, error: str | None = None, untimed: bool = False) -> None:
        ops.append(("feed", Chunk(when if timed and not untimed else None, who, data, error)))  # type: ignore[arg-type]

    for (kind, k), gap, latency, x in items:
        command, answer, wrong = PAIRS[k]
        t += gap
        host_t = t
        t += latency
        if kind == "clean":
            chunk(HOST, command, host_t)
            chunk(DEVICE, answer, t)
        elif kind == "readback":
            chunk(HOST, command, host_t)
            chunk(DEVICE, wrong, t)
        elif kind == "alarm":
            chunk(HOST, command, host_t)
            chunk(DEVICE, ALARMS[x % len(ALARMS)], t)
        elif kind == "silent":
            chunk(HOST, command, host_t)
        elif kind == "letter_o":
            chunk(HOST, b"O" + command[1:], host_t)
            chunk(DEVICE, answer, t)
        elif kind == "lower":
            chunk(HOST, command.lower(), host_t)
            chunk(DEVICE, answer.lower(), t)
        elif kind == "no_cr":
            chunk(HOST, command, host_t)
            chunk(DEVICE, answer[:-2] + b"\n", t)
        elif kind == "split_host":
            cut = 1 + x % (len(command) - 1)
            chunk(HOST, command[:cut], host_t)
            chunk(HOST, command[cut:], host_t + 0.001)
            chunk(DEVICE, answer, t + 0.001)
        elif kind == "split_device":
            cut = 1 + x % (len(answer) - 1)
            chunk(HOST, command, host_t)
            chunk(DEVICE, answer[:cut], t)
            chunk(DEVICE, answer[cut:], t + (1.0 if x % 3 == 0 else 0.001))  # the idle flush's edge
        elif kind == "error_host":
            chunk(HOST, command, host_t, "UART framing error")
            chunk(DEVICE, answer, t)
        elif kind == "error_device":
            chunk(HOST, command, host_t)
            chunk(DEVICE, answer, t, "UART parity error")
        elif kind == "junk_host":
            chunk(HOST, JUNK[x % len(JUNK)], host_t)
        elif kind == "junk_device":
            chunk(HOST, command, host_t)
            chunk(DEVICE, JUNK[x % len(JUNK)], t)
            if x % 2:
                chunk(DEVICE, answer, t + 0.002)
        elif kind == "untimed_command":
            chunk(HOST, command, host_t, untimed=True)
            chunk(DEVICE, answer, t)
        elif kind == "untimed_answer":
            chunk(HOST, command, host_t)
            chunk(DEVICE, answer, t, untimed=True)
        elif kind in ("tick", "tick_late"):  # a tick between a command and its answer
            chunk(HOST, command, host_t)
            ops.append(("tick", host_t + (latency if kind == "tick" else 1.0 + latency)))
            chunk(DEVICE, answer, t)
        elif kind == "ask":
            chunk(HOST, command, host_t)
            ops.append(("ask", None))
            chunk(DEVICE, answer, t)
        elif kind == "move":
            chunk(HOST, MOVE[0], host_t)
            chunk(DEVICE, MOVE[1], t)
        elif kind == "overlap":
            chunk(HOST, command, host_t)
            chunk(HOST, command, host_t + latency / 2)
            chunk(DEVICE, answer, t)
        elif kind == "unsolicited":
            chunk(DEVICE, answer, t)
        elif kind == "host_lf":  # a terminator without CR from the host
            chunk(HOST, command[:-2] + b"\n", host_t)
            chunk(DEVICE, answer, t)
        elif kind == "answer_and_more":  # the answer and the start of another line in one chunk
            chunk(HOST, command, host_t)
            chunk(DEVICE, answer + JUNK[x % len(JUNK)], t)
        elif kind == "backwards":  # a damaged time: the command stamped before the last answer
            chunk(HOST, command, host_t - 2.0 - gap)
            chunk(DEVICE, answer, t - 2.0)
        elif kind == "late":  # the answer just after the window closed, or long after
            chunk(HOST, command, host_t)
            chunk(DEVICE, answer, host_t + 1.0 + (1e-9 if x % 2 else 2.0))
            t = max(t, host_t + 3.0)
        else:  # pragma: no cover
            raise AssertionError(kind)
    return ops


def state(analyzer: Analyzer) -> tuple[Any, ...]:
    """Everything the analyzer and its engine keep between calls (caches of decoded frames aside)."""
    c = analyzer.conversation
    framers = tuple((f._base, bytes(f._buf), list(f._ends), list(f._times))
                    for f in analyzer._framers.values())
    return (c._next_i, c._last_t, c._answer_since, c._unreset_alarm, c.knowledge, list(c._queue), c._motion,
            framers, {d: list(e) for d, e in analyzer._errors.items()}, analyzer._device_since,
            analyzer._device_last, analyzer._closed, analyzer.tally)


def run(ops: list[Op], fast: bool, close_at: float | None,
        options: dict[str, Any] | None = None) -> tuple[list[Any], Analyzer]:
    """Every call's result, in order (the close's last), and the analyzer's state after each call
    (None while the fast lane holds a command: the engine has not seen it yet)."""
    analyzer = Analyzer(fast=fast, **(options or {}))
    out: list[Any] = []
    for what, arg in ops:
        if what == "feed":
            out.append(analyzer.feed(arg))
        elif what == "tick":
            out.append(analyzer.tick(arg))
        else:  # the summary first: it must be right while a command is held, before anything settles it
            out.append((analyzer.summary(), analyzer.waiting, analyzer.expecting_answer,
                        analyzer.bytes_in(HOST), analyzer.bytes_in(DEVICE)))
        holding = analyzer.lane is not None and analyzer.lane._held is not None
        out.append(("state", None if holding else state(analyzer)))
    out.append(analyzer.close(close_at))
    out.append(("state", state(analyzer)))
    out.append(analyzer.summary())
    out.append((analyzer.waiting, analyzer.bytes_in(HOST), analyzer.bytes_in(DEVICE)))
    return out, analyzer


def _exact(record: Record) -> tuple[type, dict[str, Any], str]:
    return type(record), dict(vars(record)), record.to_json()


def assert_same(ops: list[Op], close_at: float | None = None,
                options: dict[str, Any] | None = None) -> Analyzer:
    """The fast lane's results equal the full path's, call by call; returns the fast analyzer."""
    fast, analyzer = run(ops, True, close_at, options)
    slow, _ = run(ops, False, close_at, options)
    assert len(fast) == len(slow)
    for got, want in zip(fast, slow, strict=True):
        if isinstance(got, tuple) and got[:1] == ("state",) and got[1] is None:
            continue  # a command held: the fast analyzer's engine has not seen it yet
        assert got == want
        if isinstance(want, list):
            assert [_exact(r) for r in got] == [_exact(r) for r in want]  # fields, JSON lines
    assert json.dumps(fast[-2]) == json.dumps(slow[-2])  # the summary line
    return analyzer


def end_of(ops: list[Op]) -> float:
    times = [arg.t if what == "feed" else arg for what, arg in ops if what != "ask"]
    return max((t for t in times if t is not None), default=T0)


# the analyzer's options: another answer window, no idle flush, a storm limit of one
OPTIONS = [{}, {}, {}, {"no_answer_timeout": 0.5}, {"device_idle_flush": None}, {"storm_limit": 1}]
# the lane's bounds, small ones too: memos forgotten, the lane stepping aside often
BOUNDS = [{}, {}, {"CHANGES": 1, "BACKOFF": 1}, {"CHANGES": 2, "BACKOFF": 5, "BACKOFF_MAX": 7},
          {"MEMOS": 1, "COMMANDS": 2}, {"MEMOS": 2, "COMMANDS": 3, "CHANGES": 3, "BACKOFF": 2}]


@contextlib.contextmanager
def bounds(values: dict[str, int], module: Any = fastlane) -> Iterator[None]:
    """The module's bounds (``fastlane``'s by default) set to these values for the block."""
    with contextlib.ExitStack() as stack:
        for name, value in values.items():
            stack.enter_context(mock.patch.object(module, name, value))
        yield


@settings(max_examples=2000, deadline=None)
@given(steps, st.booleans(), st.sampled_from([None, 0.0, 0.5, 1.0, 5.0]), st.sampled_from(OPTIONS),
       st.sampled_from(BOUNDS))
@example([(("clean", 0), 0.0, 0.002, 0)] * 3 + [(("tick", 0), 0.0, 0.5, 0), (("clean", 0), 0.0, 1.0, 0)],
         True, None, {}, {})
@example([(("clean", 1), 0.0, 0.002, 0)] * 3 + [(("silent", 1), 0.0, 0.002, 0)], True, 0.999999, {}, {})
@example([(("clean", k), 0.01, 0.002, 0) for k in (3, 3, 3, 4, 4, 3, 4, 3)], True, None, {},
         {"CHANGES": 1, "BACKOFF": 1})  # the lane steps aside and back: the knowledge changed meanwhile
def test_fast_lane_gives_the_full_paths_records(items, timed, close_after, options, lane_bounds):
    ops = ops_of(items, timed)
    close_at = None if close_after is None else end_of(ops) + close_after
    with bounds(lane_bounds):
        assert_same(ops, close_at, options)


# runs of one clean exchange repeated (2 to 12 times, quick answers), each run ended by any step
runs = st.lists(st.tuples(st.integers(0, len(PAIRS) - 1), st.integers(2, 12), quick, step),
                min_size=1, max_size=12)


@settings(max_examples=800, deadline=None)
@given(runs, st.booleans(), st.sampled_from([None, 0.0, 1.0, 5.0]), st.sampled_from(OPTIONS),
       st.sampled_from(BOUNDS))
def test_fast_lane_on_runs_of_repeated_exchanges(items, timed, close_after, options, lane_bounds):
    """Long runs of hits, each ended by an anomaly (or a tick, a question, a move...)."""
    flat = []
    for k, repeat, latency, end in items:
        flat += [(("clean", k), 0.01, latency, 0)] * repeat + [end]
    ops = ops_of(flat, timed)
    with bounds(lane_bounds):
        assert_same(ops, None if close_after is None else end_of(ops) + close_after, options)


@settings(max_examples=100, deadline=None)
@given(events, gaps, cuts, st.booleans(), line_error_at)
def test_fast_lane_on_the_decode_equivalence_conversations(items, dts, sizes, timed, flagged):
    """Random traffic (few exchanges repeat): whole-frame chunks and cut ones."""
    for size in (sizes, [64]):
        ops: list[Op] = [("feed", c) for c in chunks_of(items * 3, dts * 3, size, timed, flagged)]
        assert_same(ops)


@pytest.mark.parametrize("path", corpus_cases(), ids=lambda p: p.stem)
def test_fast_lane_on_the_corpus(path):
    items, dts = read_corpus_case(path)
    for timed in (True, False):
        ops: list[Op] = [("feed", c) for c in chunks_of(items * 3, dts * 3, [64], timed)]
        assert_same(ops)
        assert_same(ops, end_of(ops) + 1.0)


def test_the_fast_lane_hits_replays_and_switches_memos():
    """A repetitive conversation with anomalies: the memo fills, answers most exchanges, replays held
    commands whose answer is not the memoised one, and survives knowledge changes (so the comparisons
    above compare the fast lane itself, not the full path with itself)."""
    items = []
    for n in range(350):
        k = n % 7  # the alarm reset (0%C) among them: an alarm answer latches until it
        kind = "clean"
        if n % 23 == 22:
            kind = ("readback", "alarm", "silent", "late", "tick", "ask", "split_device")[n // 23 % 7]
        items.append(((kind, k), 0.01, 0.002 if n % 5 else 0.999999, n))
    ops = ops_of(items, timed=True)
    analyzer = assert_same(ops)
    lane = analyzer.lane
    assert lane is not None
    assert lane.hits > 150 and lane.replays > 3
    assert len(lane._memos) > 1  # more than one value of the knowledge memoised
    untimed = assert_same(ops_of(items, timed=False))
    assert untimed.lane is not None and untimed.lane.hits > 150


def test_a_hit_at_the_window_edge_and_just_past_it():
    """The answer at exactly the deadline is a hit; 1 us later the command is no-answer (full path)."""
    c, a, _ = PAIRS[0]
    ops: list[Op] = []
    t = T0
    for _ in range(3):
        ops += [("feed", Chunk(t, HOST, c)), ("feed", Chunk(t + 0.002, DEVICE, a))]
        t += 0.01
    ops += [("feed", Chunk(t, HOST, c)), ("feed", Chunk(t + 1.0, DEVICE, a))]
    analyzer = assert_same(ops)
    assert analyzer.lane is not None and analyzer.lane.hits == 2
    t += 2.0
    ops += [("feed", Chunk(t, HOST, c)), ("feed", Chunk(t + 1.000001, DEVICE, a))]
    analyzer = assert_same(ops)
    assert analyzer.lane is not None and analyzer.lane.hits == 2 and analyzer.lane.replays == 1


def test_the_held_command_is_returned_at_once():
    """A held command's record comes back from its own feed (per-chunk outputs are what an annotated
    capture writes), and ``summary`` counts it before its answer."""
    c, a, _ = PAIRS[0]
    analyzer = Analyzer()
    for n in range(3):
        assert len(analyzer.feed(Chunk(T0 + n, HOST, c))) == 1
        assert len(analyzer.feed(Chunk(T0 + n + 0.002, DEVICE, a))) == 1
    assert analyzer.lane is not None and analyzer.lane.hits == 1
    got = analyzer.feed(Chunk(T0 + 5, HOST, c))
    assert [type(r) for r in got] == [FrameRecord] and analyzer.lane._held is not None
    assert analyzer.summary()["frames"] == {"host": 4, "device": 3}
    assert analyzer.waiting and analyzer.lane._held is None  # the question settled it


def test_tally_add_clean_frame_counts_as_add():
    """The fast lane's tally update counts clean frames as ``Tally.add`` did before it was split out (the
    reference kept in test_decode_equivalence), the forgetting of commands never answered (over 4096
    waiting) included; ``add`` itself is proven equal to that reference there."""
    from sniffer.records import Tally

    ra, rv = fr.ReadVersion(), fr.ReadVersionAnswer(version="100")
    records: list[FrameRecord] = []
    for i in range(0, 20_000, 2):
        records.append(FrameRecord(i=i, t=T0 + i, dir="host", raw=ra.to_bytes(), header="0RV", frame=ra,
                                   t_last=T0 + i, window_s=1.0))
        if i % 3 == 0 or i > 19_000:  # most commands left unanswered, then answers to old and new ones
            reply_to = i if i % 3 == 0 else i - 19_000
            records.append(FrameRecord(i=i + 1, t=T0 + i + 0.002, dir="device", raw=rv.to_bytes(),
                                       header="0RV", frame=rv, reply_to=reply_to, latency_s=0.002 * (i % 7),
                                       t_last=T0 + i + 0.002))
    records.append(FrameRecord(i=20_001, t=None, dir="device", raw=rv.to_bytes(), header=None, frame=None))
    added, clean = Tally(), Tally()
    peak = 0
    for r in records:
        _reference_tally_add(added, r)
        clean.add_clean_frame(r)
        assert clean == added
        peak = max(peak, len(added._headers))
    assert clean.summary() == added.summary() and peak == 4096  # the oldest were forgotten


def test_an_alarm_answer_that_changes_no_knowledge_is_not_memoised():
    """With emergency stop (0E) latched after a reset that failed, a command answered 0%%0E changes no
    knowledge, but leaves an alarm to reset (alarm-ignored on the next command): never a memo entry."""
    reset, _, failed = PAIRS[6]
    c, a, _ = PAIRS[0]
    estop = fr.AlarmAnswer(code=0x0E).to_bytes()
    items = [(("clean", 0), 0.01, 0.002, 0)] * 3
    ops = ops_of(items, timed=True)
    t = end_of(ops)
    for _ in range(4):
        for who, data in ((HOST, reset), (DEVICE, failed), (HOST, c), (DEVICE, estop)):
            t += 0.01
            ops.append(("feed", Chunk(t, who, data)))  # type: ignore[arg-type]
    assert_same(ops)


@pytest.mark.parametrize(("memos", "commands"), [(2, 3), (1, 1), (3, 100)])
def test_the_bounds_forget_memos_and_change_nothing(monkeypatch, memos, commands):
    """Few memos and few commands allowed: the least recently used memos are forgotten, the records stay
    the full path's."""
    from sniffer import fastlane

    monkeypatch.setattr(fastlane, "MEMOS", memos)
    monkeypatch.setattr(fastlane, "COMMANDS", commands)
    items = []
    for n in range(350):
        kind = "clean" if n % 11 else ("readback", "alarm", "silent")[n // 11 % 3]
        items.append(((kind, n % 7), 0.01, 0.002, n))
    analyzer = assert_same(ops_of(items, timed=True))
    lane = analyzer.lane
    assert lane is not None and lane.hits > 0
    assert len(lane._memos) <= max(memos, 2) and lane._commands <= commands
    assert lane._commands == sum(len(m) for m in lane._memos.values())


@pytest.mark.parametrize(("changes", "backoff"), [(8, 64), (2, 3), (1, 1)])
def test_exchanges_that_change_the_knowledge_back_the_lane_off(monkeypatch, changes, backoff):
    """Clean exchanges that each write new point values are never memoised: the lane backs off (the
    full path alone) and looks again; the repeated exchanges after them are memoised again."""
    from sniffer import fastlane

    monkeypatch.setattr(fastlane, "CHANGES", changes)
    monkeypatch.setattr(fastlane, "BACKOFF", backoff)
    ops: list[Op] = []
    t = T0
    for n in range(240):
        if n % 80 < 25:  # a new value for point 1..15 every time, an echo of it
            c: fr.Frame = fr.WritePoint(n=n % 15 + 1, v=n % 9 + 1, a=1, o=0, pos=n)
            a: fr.Frame = fr.WritePointAnswer(n=n % 15 + 1, v=n % 9 + 1, a=1, o=0, pos=n)
        else:
            c, a = fr.ReadVersion(), fr.ReadVersionAnswer(version="100")
        t += 0.01
        ops += [("feed", Chunk(t, HOST, c.to_bytes())), ("feed", Chunk(t + 0.002, DEVICE, a.to_bytes()))]
    analyzer = assert_same(ops, end_of(ops) + 2.0)
    assert analyzer.lane is not None and analyzer.lane.hits > 10


def test_ticks_between_commands_and_answers_make_the_lane_step_aside():
    """The live sniffer's polls: a tick between each command and its answer. A held command is replayed
    by the tick, an observed one forgotten, so after a few the lane steps aside (as for exchanges that
    keep changing the knowledge); the records stay the full path's."""
    ops: list[Op] = []
    t = T0
    for n in range(400):
        c, a, _ = PAIRS[n % 3]
        ops.append(("feed", Chunk(t, HOST, c)))
        if n >= 100:  # first learnt without ticks, then held and replayed by every tick
            ops.append(("tick", t + 0.001))
        ops.append(("feed", Chunk(t + 0.002, DEVICE, a)))
        t += 0.01
    analyzer = assert_same(ops)
    lane = analyzer.lane
    assert lane is not None and lane.hits > 80
    # 300 exchanges with ticks: CHANGES replays, then 32, 64, 128 exchanges aside, and so on
    assert lane.replays <= 5 * fastlane.CHANGES
    assert lane._backoff > 2 * fastlane.BACKOFF  # more than once, each time for longer
