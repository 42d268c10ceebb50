"""``Analyzer.feed_many`` (the fast lane's stretches: exchanges answered from the memo taken in one loop,
their bookkeeping done once) changes nothing: fed the same chunks, it gives the records that ``feed``
gives one chunk at a time on the full path (``Analyzer(fast=False)``), in order, field by field and as
JSON lines, and leaves the same state and summary. With ``clean=False`` it may leave out clean frame
records only: every other record still comes, in order, and the summary is the same.

The conversations are those of tests/test_fastlane_equivalence.py (repeated clean exchanges with every
kind of anomaly, ticks and questions between the runs of chunks), cut into runs of chunks each given to
one ``feed_many`` with batch sizes from 1 up; exchanges that change the knowledge (``0RS`` learns the OUT
ports that ``0WS`` then establishes) are memoised as transitions and replayed by the stretches too.
"""

from __future__ import annotations

import io
import json
from collections.abc import Iterator
from typing import Any

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_decode_equivalence import (
    chunks_of,
    corpus_cases,
    cuts,
    events,
    gaps,
    line_error_at,
    read_corpus_case,
)
from test_fastlane_equivalence import (
    BOUNDS,
    OPTIONS,
    PAIRS,
    T0,
    Op,
    _exact,
    bounds,
    end_of,
    ops_of,
    runs,
    state,
    steps,
)

from sniffer.analyzer import Analyzer
from sniffer.records import CleanExchange, FrameRecord, Record
from sniffer.view import JsonlView
from xac1_proto import frames as fr
from xac1_proto.chunk import DEVICE, HOST, Chunk

BATCHES = [1, 2, 3, 7, 64, 1024]


def _groups(ops: list[Op]) -> list[tuple[str, Any]]:
    """The calls with consecutive feeds gathered: ("chunks", [Chunk, ...]), ("tick", now), ("ask", None)."""
    out: list[tuple[str, Any]] = []
    for what, arg in ops:
        if what == "feed":
            if out and out[-1][0] == "chunks":
                out[-1][1].append(arg)
            else:
                out.append(("chunks", [arg]))
        else:
            out.append((what, arg))
    return out


def _run(ops: list[Op], fast: bool, close_at: float | None, options: dict[str, Any], clean: bool,
         batch: int, lean: bool = False) -> tuple[list[Any], Analyzer]:
    """Each group's result and the state after it; the fast analyzer takes each run of chunks through one
    ``feed_many`` (``lean``: each ``CleanExchange`` it gives expanded into its records), the reference
    feeds them one at a time on the full path."""
    analyzer = Analyzer(fast=fast, **options)
    out: list[Any] = []
    for what, arg in _groups(ops):
        if what == "chunks":
            if fast:
                got: list[Record] = []
                chunks = iter(arg)
                taken = []
                while n := analyzer.feed_many(chunks, got, clean, batch, lean):  # type: ignore[arg-type]
                    taken.append(n)
                assert sum(taken) == len(arg) and max(taken) <= batch + 1  # about ``batch`` a call
                got = [r for x in got for r in (x.records() if type(x) is CleanExchange else (x,))]
            else:
                got = [r for chunk in arg for r in analyzer.feed(chunk)]
            out.append(got)
        elif what == "tick":
            out.append(analyzer.tick(arg))
        else:
            out.append((analyzer.summary(), analyzer.waiting, analyzer.expecting_answer,
                        analyzer.bytes_in(HOST), analyzer.bytes_in(DEVICE)))
        holding = analyzer.lane is not None and analyzer.lane._held is not None
        out.append(("state", None if holding else state(analyzer)))
    out.append(analyzer.close(close_at))
    out.append(("state", state(analyzer)))
    out.append(analyzer.summary())
    return out, analyzer


def _kept(records: list[Record]) -> list[Record]:
    """What ``clean=False`` must keep: every record but clean frame records."""
    return [r for r in records if type(r) is not FrameRecord or r.violations or r.line_errors]


def _subsequence(part: list[Record], whole: list[Record]) -> bool:
    it = iter(whole)
    return all(any(r is w or r == w for w in it) for r in part)


def assert_same(ops: list[Op], close_at: float | None = None, options: dict[str, Any] | None = None,
                clean: bool = True, batch: int = 1024, lean: bool = False) -> Analyzer:
    fast, analyzer = _run(ops, True, close_at, options or {}, clean, batch, lean)
    slow, _ = _run(ops, False, close_at, options or {}, True, batch)
    assert len(fast) == len(slow)
    for got, want in zip(fast, slow, strict=True):
        if isinstance(got, tuple) and got[:1] == ("state",) and got[1] is None:
            continue  # a command held: the fast analyzer's engine has not seen it yet
        if isinstance(want, list) and not clean:
            assert _kept(got) == _kept(want)
            assert [_exact(r) for r in _kept(got)] == [_exact(r) for r in _kept(want)]
            assert _subsequence(got, want)
            continue
        assert got == want
        if isinstance(want, list):
            assert [_exact(r) for r in got] == [_exact(r) for r in want]  # fields, JSON lines
    assert json.dumps(fast[-1]) == json.dumps(slow[-1])  # the summary line
    return analyzer


@settings(max_examples=1500, deadline=None)
@given(steps, st.booleans(), st.sampled_from([None, 0.0, 0.5, 1.0, 5.0]), st.sampled_from(OPTIONS),
       st.sampled_from(BOUNDS), st.booleans(), st.sampled_from(BATCHES))
@example([(("clean", 3), 0.0, 0.002, 0), (("clean", 4), 0.0, 0.002, 0)] * 6, True, None, {}, {}, True, 1024)
def test_feed_many_gives_the_full_paths_records(items, timed, close_after, options, lane_bounds, clean,
                                                batch):
    ops = ops_of(items, timed)
    close_at = None if close_after is None else end_of(ops) + close_after
    with bounds(lane_bounds):
        assert_same(ops, close_at, options, clean, batch)


@settings(max_examples=600, deadline=None)
@given(steps, st.booleans(), st.sampled_from([None, 0.0, 1.0]), st.sampled_from(OPTIONS),
       st.sampled_from(BOUNDS), st.sampled_from(BATCHES))
def test_feed_many_lean_gives_the_full_paths_records_and_json_lines(items, timed, close_after, options,
                                                                     lane_bounds, batch):
    """``lean``: each exchange a stretch takes comes as a ``CleanExchange``; its ``records()`` are the full
    path's records, and the JSON lines view prints exactly the lines of those records."""
    ops = ops_of(items, timed)
    close_at = None if close_after is None else end_of(ops) + close_after
    with bounds(lane_bounds):
        assert_same(ops, close_at, options, True, batch, lean=True)
        analyzer = Analyzer(**options)
        given_: list[Any] = []
        chunks = iter([c for what, c in ops if what == "feed"])
        while analyzer.feed_many(chunks, given_, True, batch, lean=True):
            pass
    reference = Analyzer(fast=False, **options)
    records = [r for what, c in ops if what == "feed" for r in reference.feed(c)]
    lean_lines, record_lines = io.StringIO(), io.StringIO()
    for stream, items_given in ((lean_lines, given_), (record_lines, records)):
        view = JsonlView(stream, live=False)
        view.write_many(items_given)
        view.flush()
    assert lean_lines.getvalue() == record_lines.getvalue()
    assert record_lines.getvalue() == "".join(r.to_json() + "\n" for r in records)


def test_a_lean_stretch_gives_clean_exchanges():
    """The alternating conversation's stretches come as ``CleanExchange``s (so the comparison above compares
    them, not the records of ``feed``)."""
    analyzer = Analyzer()
    given_: list[Any] = []
    chunks = iter([c for _, c in _alternating(200)])
    while analyzer.feed_many(chunks, given_, lean=True):
        pass
    assert sum(1 for item in given_ if type(item) is CleanExchange) > 150


@settings(max_examples=800, deadline=None)
@given(runs, st.booleans(), st.sampled_from([None, 0.0, 1.0]), st.sampled_from(OPTIONS),
       st.sampled_from(BOUNDS), st.booleans(), st.sampled_from(BATCHES))
def test_feed_many_on_runs_of_repeated_exchanges(items, timed, close_after, options, lane_bounds, clean,
                                                 batch):
    """Long stretches, each ended by an anomaly (or a tick, a question, a move...)."""
    flat = []
    for k, repeat, latency, end in items:
        flat += [(("clean", k), 0.01, latency, 0)] * repeat + [end]
    ops = ops_of(flat, timed)
    with bounds(lane_bounds):
        assert_same(ops, None if close_after is None else end_of(ops) + close_after, options, clean, batch)


@settings(max_examples=100, deadline=None)
@given(events, gaps, cuts, st.booleans(), line_error_at, st.booleans(), st.sampled_from(BATCHES))
def test_feed_many_on_the_decode_equivalence_conversations(items, dts, sizes, timed, flagged, clean, batch):
    """Random traffic (few exchanges repeat): whole-frame chunks and cut ones."""
    for size in (sizes, [64]):
        ops: list[Op] = [("feed", c) for c in chunks_of(items * 3, dts * 3, size, timed, flagged)]
        assert_same(ops, None, None, clean, batch)


def test_feed_many_on_the_corpus():
    for path in corpus_cases():
        items, dts = read_corpus_case(path)
        for timed in (True, False):
            ops: list[Op] = [("feed", c) for c in chunks_of(items * 3, dts * 3, [64], timed)]
            assert_same(ops)
            assert_same(ops, end_of(ops) + 1.0, clean=False, batch=3)


def _alternating(n: int) -> list[Op]:
    """Read the outputs, write them, read a version, over and over: 0RS and 0WS each change what is
    known of the OUT ports (learnt, then known) whenever the other came last."""
    ops: list[Op] = []
    t = T0
    for k in range(n):
        command, answer, _ = PAIRS[(3, 4, 0, 4, 3)[k % 5]]
        ops += [("feed", Chunk(t, HOST, command)), ("feed", Chunk(t + 0.002, DEVICE, answer))]
        t += 0.01
    return ops


def test_exchanges_that_change_the_knowledge_are_replayed_as_transitions():
    """An exchange that changes the knowledge in the same way each time is memoised with that change:
    after the first rounds every exchange comes from the memo, in stretches, the knowledge carried along
    (so the comparisons above compare transitions too, not the full path with itself)."""
    ops = _alternating(600)
    analyzer = assert_same(ops, end_of(ops) + 2.0)
    lane = analyzer.lane
    assert lane is not None and lane.hits > 590
    assert analyzer.conversation.knowledge.outputs.status == "learnt"  # the last exchange was 0RS
    assert assert_same(ops, clean=False, batch=5).lane.hits > 590  # type: ignore[union-attr]


def test_clean_false_leaves_out_only_what_it_does_not_make():
    """A long clean stretch with one violation in it: ``clean=False`` gives the violation's records (and
    the records the stretch did not take), never fewer, and counts everything in the summary."""
    ops = _alternating(300)
    t = end_of(ops) + 0.01
    wrong = fr.ReadOutputsAnswer(o=3).to_bytes()
    ops += [("feed", Chunk(t, HOST, PAIRS[3][0])), ("feed", Chunk(t + 0.002, DEVICE, wrong))]
    analyzer = Analyzer()
    got: list[Record] = []
    chunks = iter([c for _, c in ops])
    while analyzer.feed_many(chunks, got, clean=False):
        pass
    assert any(r.violations for r in got)
    assert len(got) < 40  # the stretches' clean records not made
    assert analyzer.summary()["frames"] == {"host": 301, "device": 301}
    assert_same(ops, clean=False)


class _Stop(Exception):
    pass


@settings(max_examples=200, deadline=None)
@given(runs, st.booleans(), st.integers(0, 400), st.sampled_from(BATCHES))
def test_an_exception_from_the_chunks_loses_nothing(items, timed, stop_at, batch):
    """The chunk iterator fails part way (a reader's error, Ctrl-C), inside a stretch or not: the records
    of every chunk taken before it are in ``out`` and the state is what ``feed`` leaves after them, so the
    analyzer goes on (here: with the rest of the chunks) exactly as the full path."""
    flat = []
    for k, repeat, latency, end in items:
        flat += [(("clean", k), 0.01, latency, 0)] * repeat + [end]
    chunks = [arg for what, arg in ops_of(flat, timed) if what == "feed"]
    stop_at = min(stop_at, len(chunks))

    def failing() -> Iterator[Chunk]:
        yield from chunks[:stop_at]
        raise _Stop

    fast, slow = Analyzer(), Analyzer(fast=False)
    got: list[Record] = []
    with pytest.raises(_Stop):
        iterator = failing()
        while fast.feed_many(iterator, got, True, batch):
            pass
    want = [r for chunk in chunks[:stop_at] for r in slow.feed(chunk)]
    assert got == want
    assert fast.summary() == slow.summary()
    rest = iter(chunks[stop_at:])
    while fast.feed_many(rest, got, True, batch):
        pass
    want += [r for chunk in chunks[stop_at:] for r in slow.feed(chunk)]
    got += fast.close()
    want += slow.close()
    assert got == want and state(fast) == state(slow) and fast.summary() == slow.summary()
