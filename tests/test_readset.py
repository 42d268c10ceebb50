"""The fast lane's reads memo (``sniffer/readset.py``): exchanges kept by the part of the knowledge the
engine read while judging them, replayed under any knowledge that holds the same values there.

First the tracer itself, on the real engine: what it notes for each kind of exchange, and that the
knowledge is the same plain object with the same ``points`` dict afterwards, even when the call raises.
Then equivalence with the full path (``Analyzer(fast=False)``), call by call (``feed``) and in bulk
(``feed_many``), on conversations over several points where anomalies keep changing the knowledge
(a point forgotten after a garbled or missing answer, learnt again later): the traffic the whole-
knowledge memo cannot serve and this one must, with the memos' bounds small and large.
"""

from __future__ import annotations

import pytest
import test_feed_many_equivalence as bulk
from hypothesis import given, settings
from hypothesis import strategies as st
from test_fastlane_equivalence import BOUNDS, OPTIONS, T0, Op, assert_same, bounds, end_of

from sniffer import readset
from sniffer.analyzer import Analyzer
from xac1_proto import codec, spec
from xac1_proto import frames as fr
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.conversation import Knowledge

POINTS = (1, 2, 5)
_VALUES = {n: dict(n=n, v=n + 2, a=2, o=n % 4, pos=0x1000 * n + 0x34) for n in POINTS}
# (command, answer) pairs: each point read and written, the version, the outputs read and written
PAIRS: list[tuple[bytes, bytes]] = [(c.to_bytes(), a.to_bytes()) for c, a in [
    *[(fr.ReadPoint(n=n), fr.ReadPointAnswer(**_VALUES[n])) for n in POINTS],
    *[(fr.WritePoint(**_VALUES[n]), fr.WritePointAnswer(**_VALUES[n])) for n in POINTS],
    (fr.ReadVersion(), fr.ReadVersionAnswer(version="100")),
    (fr.ReadOutputs(), fr.ReadOutputsAnswer(o=1)),
    (fr.WriteOutputs(o=1), fr.WriteOutputsAnswer(o=1)),
]]
FAULTS = ("garbled", "silent", "readback", "echo", "alarm", "clean", "clean", "clean")
READS_BOUNDS = [{}, {}, {"VARIANTS": 1}, {"ENTRIES": 3}, {"VARIANTS": 2, "ENTRIES": 7}]


def _fault(kind: str, command: bytes, answer: bytes) -> tuple[bytes, bytes | None]:
    """The exchange broken one way: (command, answer or None for silence)."""
    if kind == "garbled":  # device junk in the window: what the command did is unknown now
        return command, answer[:4] + b"\xff" + answer[5:]
    if kind == "silent":
        return command, None
    if kind == "readback" and len(answer) > 8:  # another value read back (or echoed)
        last = answer[-3:-2]
        return command, answer[:-3] + (b"0" if last != b"0" else b"1") + answer[-2:]
    if kind == "echo" and command[:3] == answer[:3] and len(command) > 8:  # the echo of other values
        return command, answer[:3] + (b"1" if answer[3:4] != b"1" else b"2") + answer[4:]
    if kind == "alarm":
        return command, fr.AlarmAnswer(code=0x01).to_bytes() if len(answer) % 2 else answer
    return command, answer


# one exchange: (pair, fault or "clean", gap, latency)
exchange = st.tuples(st.integers(0, len(PAIRS) - 1),
                     st.one_of(st.just("clean"), st.just("clean"), st.sampled_from(FAULTS)),
                     st.sampled_from([0.001, 0.01, 0.5]), st.sampled_from([0.001, 0.002, 0.999999, 1.5]))
conversations = st.lists(exchange, min_size=4, max_size=120)


def ops_of(items: list[tuple[int, str, float, float]], timed: bool) -> list[Op]:
    ops: list[Op] = []
    t = T0
    for k, kind, gap, latency in items:
        command, answer = _fault(kind, *PAIRS[k])
        t += gap
        ops.append(("feed", Chunk(t if timed else None, HOST, command)))
        if kind == "alarm" and answer != PAIRS[k][1]:  # reset it, as a careful host does
            t += latency
            ops.append(("feed", Chunk(t if timed else None, DEVICE, answer)))
            reset, done = fr.AlarmReset().to_bytes(), fr.AlarmResetAnswer().to_bytes()
            ops += [("feed", Chunk(t + 0.01 if timed else None, HOST, reset)),
                    ("feed", Chunk(t + 0.012 if timed else None, DEVICE, done))]
            t += 0.02
            continue
        t += latency
        if answer is not None:
            ops.append(("feed", Chunk(t if timed else None, DEVICE, answer)))
        else:
            t += 1.5
    return ops


def _mixed(n: int, every: int = 7) -> list[tuple[int, str, float, float]]:
    """A deterministic conversation: every ``every``-th exchange a fault, cycling through them."""
    faults = ("garbled", "silent", "readback", "echo")
    return [(k * 5 % len(PAIRS), faults[k // every % len(faults)] if k % every == every - 1 else "clean",
             0.01, 0.002) for k in range(n)]


# ---- the tracer ----

def _traced(analyzer: Analyzer, chunk: Chunk) -> readset.Trace:
    tracer = readset.Tracer()
    with tracer.watching(analyzer.conversation.knowledge) as trace:
        analyzer._feed(chunk)
    return trace


def test_the_tracer_notes_what_each_exchange_reads_and_writes():
    analyzer = Analyzer(fast=False)
    k = analyzer.conversation.knowledge
    points = k.points
    read_3, answer_3 = fr.ReadPoint(n=3).to_bytes(), fr.ReadPointAnswer(n=3, v=1, a=1, o=0, pos=5).to_bytes()
    asked = _traced(analyzer, Chunk(T0, HOST, read_3))
    assert asked.reads == {"storm_run"} and not asked.wrote  # the storm rule reads the run: nothing else
    answered = _traced(analyzer, Chunk(T0 + 0.01, DEVICE, answer_3))
    assert answered.point_reads == {3} and answered.point_writes == {3}  # not known yet: learnt
    assert "latched" in answered.reads and {"storm_run", "mode"} <= answered.writes
    assert not answered.whole
    write_7 = fr.WritePoint(n=7, v=1, a=1, o=0, pos=5)
    _traced(analyzer, Chunk(T0 + 0.02, HOST, write_7.to_bytes()))
    echo_7 = fr.WritePointAnswer(n=7, v=1, a=1, o=0, pos=5)
    echoed = _traced(analyzer, Chunk(T0 + 0.03, DEVICE, echo_7.to_bytes()))
    assert echoed.point_writes == {7} and 7 not in echoed.point_reads  # established, whatever was known
    assert type(k) is Knowledge and k.points is points and set(points) == {3, 7}  # plain again, same dict


def test_the_tracer_puts_everything_back_when_the_call_raises():
    k = Knowledge()
    points = k.points
    tracer = readset.Tracer()
    with pytest.raises(RuntimeError), tracer.watching(k) as trace:
        k.points[4] = "x"
        _ = k.latched
        raise RuntimeError("stop")
    assert type(k) is Knowledge and k.points is points and points == {4: "x"}
    assert trace.point_writes == {4} and trace.reads == {"latched"}


@pytest.mark.parametrize("touch", [
    lambda k: list(k.points), lambda k: len(k.points), lambda k: dict(k.points), lambda k: k.points.items(),
    lambda k: k.points == {}, lambda k: vars(k), lambda k: setattr(k, "points", {}),
    lambda k: k.points.update({1: 2}), lambda k: k.points.clear()])
def test_whatever_touches_the_knowledge_as_a_whole_is_not_kept_by_parts(touch):
    k = Knowledge(points={1: "a"})
    with readset.Tracer().watching(k) as trace:
        touch(k)
    assert trace.whole and trace.wrote
    assert type(k) is Knowledge and type(k.points) is dict


def test_reads_hold_and_writes_apply_with_missing_points():
    """A point that was not there is read as ``MISSING`` (only a knowledge without it holds that), and a
    write that left it out drops it."""
    known = Knowledge(points={2: "b", 3: "c"})
    reads = readset.Reads((("storm_run", 0),), ((1, readset.MISSING), (2, "b")))
    assert reads.hold(known)
    assert not reads.hold(Knowledge(points={1: "a", 2: "b"}))
    assert not reads.hold(Knowledge(points={3: "c"}))
    assert not reads.hold(Knowledge(storm_run=1, points={2: "b"}))
    readset.Writes((("storm_run", 0), ("version", "v")), ((2, readset.MISSING), (4, "d"))).apply(known)
    assert known.points == {3: "c", 4: "d"} and known.version == "v"


# ---- the reads memo in the lane ----

def test_exchanges_come_from_the_reads_memo_when_the_whole_knowledge_keeps_changing():
    """Anomalies every seventh exchange keep changing the knowledge (so the whole-knowledge memo misses
    often); the reads memo answers most of those misses, and every record is the full path's."""
    ops = ops_of(_mixed(700), timed=True)
    analyzer = assert_same(ops, end_of(ops) + 2.0)
    lane = analyzer.lane
    assert lane is not None
    assert lane.reads.hits > 100 and lane.hits > 450
    untimed = assert_same(ops_of(_mixed(300), timed=False))
    assert untimed.lane is not None and untimed.lane.reads.hits > 30


@settings(max_examples=1000, deadline=None)
@given(conversations, st.booleans(), st.sampled_from([None, 0.0, 1.0, 5.0]), st.sampled_from(OPTIONS),
       st.sampled_from(BOUNDS), st.sampled_from(READS_BOUNDS))
def test_the_reads_memo_gives_the_full_paths_records(items, timed, close_after, options, lane_bounds,
                                                      memo_bounds):
    ops = ops_of(items, timed)
    close_at = None if close_after is None else end_of(ops) + close_after
    with bounds(lane_bounds), bounds(memo_bounds, readset):
        assert_same(ops, close_at, options)


@settings(max_examples=500, deadline=None)
@given(conversations, st.booleans(), st.sampled_from([None, 1.0]), st.sampled_from(BOUNDS),
       st.sampled_from(READS_BOUNDS), st.booleans(), st.sampled_from(bulk.BATCHES))
def test_the_reads_memo_in_bulk_gives_the_full_paths_records(items, timed, close_after, lane_bounds,
                                                             memo_bounds, clean, batch):
    ops = ops_of(items, timed)
    close_at = None if close_after is None else end_of(ops) + close_after
    with bounds(lane_bounds), bounds(memo_bounds, readset):
        bulk.assert_same(ops, close_at, {}, clean, batch)


# ---- the cache of faulty frames' diagnoses ----

@settings(max_examples=500, deadline=None)
@given(st.one_of(st.binary(max_size=24), st.sampled_from([a for _, a in PAIRS]).map(
    lambda a: a[:4] + b"\xff" + a[5:])), st.sampled_from(spec.ROLES))
def test_a_diagnosis_from_the_cache_is_the_one_made_anew(data, role):
    first = codec.diagnose(data, role)
    first[1].append("changed by the caller")  # a fresh list each time: the cache is not the caller's
    again = codec.diagnose(data, role)
    made = codec.decode_clean(data, role)
    if made is None:
        frame, found = codec._diagnose_faulty.__wrapped__(data, role)
        assert again == (frame, list(found))
    else:
        assert again == (made, [])
    assert "changed by the caller" not in again[1]
