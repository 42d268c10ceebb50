"""The conversation analyzer on scripted chunks: each rule of docs/protocol.md "Violation codes" fires on the
record the analyzer's docstring names, and nothing else fires; chunking never changes the verdicts."""

from __future__ import annotations

import json

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

from sniffer.analyzer import Analyzer, analyze
from sniffer.records import FrameRecord, JunkRecord, TimeoutRecord
from xac1_proto.chunk import Chunk

H, D = "host", "device"


def run(script, **options):
    """script: (t, dir, bytes) items; returns records."""
    return analyze([Chunk(t, d, b) for t, d, b in script], **options)


def codes(records):
    """(dir or type, violations) for every record that has violations."""
    return [(r.type if isinstance(r, TimeoutRecord) else r.dir, r.violations)
            for r in records if r.violations]


def all_codes(records):
    return sorted(c for r in records for c in r.violations)


def test_clean_exchange_pairs_and_measures_latency():
    """A command and its answer pair first in, first out; latency is the command's last byte to the
    answer's first byte (docs/protocol.md "Violation codes": answers pair first in, first out)."""
    recs = run([(10.0, H, b"0RP3\r\n"), (10.0025, D, b"0RP39302012345\r\n")])
    assert [r.type for r in recs] == ["frame", "frame"]
    cmd, ans = recs
    assert cmd.fields == {"n": 3} and ans.reply_to == 0
    assert abs(ans.latency_ms - 2.5) < 1e-6
    assert all_codes(recs) == []
    line = json.loads(ans.to_json())
    assert line == {"type": "frame", "i": 1, "t": 10.0025, "dir": "device",
                    "raw": b"0RP39302012345\r\n".hex(), "header": "0RP",
                    "fields": {"n": 3, "v": 9, "a": 3, "o": 0, "pos": 0x12345},
                    "violations": [], "sides": [], "severities": [], "reply_to": 0, "latency_ms": 2.5}


def test_letter_o_then_alarm_then_no_reset():
    """letter-o is a frame-level violation on the command; the host going on after the alarm answer without
    a reset is alarm-ignored on the next command (docs/protocol.md "Violation codes")."""
    recs = run([(0, H, b"ORP3\r\n"), (0.01, D, b"0%%01\r\n"), (0.1, H, b"0RV\r\n"), (0.11, D, b"0%%01\r\n"),
                (0.2, H, b"0%C\r\n"), (0.21, D, b"0%C00\r\n"),
                (0.3, H, b"0RV\r\n"), (0.31, D, b"0RV100\r\n")])
    assert codes(recs) == [(H, ("letter-o",)), (H, ("alarm-ignored",))]


def test_echo_mismatch_and_answer_mismatch():
    """An echo answer with other fields is echo-mismatch; an answer of another command or another N is
    answer-mismatch (docs/protocol.md "Violation codes")."""
    recs = run([(0, H, b"0WS12\r\n"), (0.01, D, b"0WS02\r\n"), (0.1, H, b"0RP3\r\n"),
                (0.11, D, b"0RP49302012345\r\n"), (0.2, H, b"0RC\r\n"), (0.21, D, b"0RS02\r\n"),
                (0.3, H, b"0RV\r\n"), (0.31, D, b"0%C00\r\n")])
    assert codes(recs) == [(D, ("echo-mismatch",)), (D, ("answer-mismatch",)), (D, ("answer-mismatch",)),
                           (D, ("answer-mismatch",))]


def test_lowercase_echo_is_only_a_notice():
    """An echo compares decoded fields, so an upper-case echo of a lower-case command is no echo-mismatch;
    lower case is the lowercase-hex notice (docs/protocol.md "Framing")."""
    recs = run([(0, H, b"0WP1930200abcd\r\n"), (0.01, D, b"0WP1930200ABCD\r\n")])
    assert codes(recs) == [(H, ("lowercase-hex",))]


def test_unsolicited_and_no_answer():
    """An answer with nothing waiting is unsolicited-answer; a command whose 1 s passes unanswered gets a
    no-answer timeout record (docs/protocol.md silent item 17), and its late answer is unsolicited."""
    recs = run([(0, D, b"0RV100\r\n"), (1.0, H, b"0RV\r\n"), (2.5, D, b"0RV100\r\n")])
    assert codes(recs) == [(D, ("unsolicited-answer",)), ("timeout", ("no-answer",)),
                           (D, ("unsolicited-answer",))]
    timeout = recs[2]
    assert timeout.command == 1 and timeout.t == 2.0 and timeout.waited_s == 1.0


def test_answer_that_starts_in_time_is_in_time():
    """The no-answer deadline applies to the answer's first byte: an answer begun before it and finished
    after it pairs normally (docs/protocol.md silent item 17)."""
    recs = run([(0, H, b"0RV\r\n"), (0.99, D, b"0RV"), (1.2, D, b"100\r\n")])
    assert all_codes(recs) == [] and recs[-1].reply_to == 0


def test_no_answer_without_time_only_at_end():
    """Without timestamps pairing is by order and a missing answer is found at the end of the data."""
    recs = run([(None, H, b"0RV\r\n"), (None, D, b"0RV100\r\n"), (None, H, b"0RC\r\n")])
    assert codes(recs) == [("timeout", ("no-answer",))]
    assert recs[1].latency_ms is None and recs[2].t is None


def test_capture_cut_short_is_not_no_answer():
    """A command whose deadline had not passed when the data ended is counted as waiting, not failed."""
    a = Analyzer()
    recs = a.feed(Chunk(0.0, H, b"0RV\r\n")) + a.close()
    assert all_codes(recs) == [] and a.summary()["unanswered"] == 1


def test_move_gets_a_longer_deadline():
    """A move's deadline is its estimated time doubled plus the timeout (silent item 17): a 0MV of known
    start answered after 3 s is fine, a 0RV answered after 3 s is not."""
    # 0MP0 from position 0: homing of no distance; then 0MV 01 (500 p/s) to 1000 pulses: 2.4 s estimated
    recs = run([(0, H, b"0RC\r\n"), (0.01, D, b"0RC00002000000\r\n"),
                (0.1, H, b"0MV0110003E8\r\n"), (3.1, D, b"0MV0110003E8\r\n"),
                (4.0, H, b"0RV\r\n"), (7.0, D, b"0RV100\r\n")])
    assert codes(recs) == [("timeout", ("no-answer",)), (D, ("unsolicited-answer",))]


def test_command_during_motion_and_overlap():
    """A host frame while a move waits is command-during-motion (not also overlapping-command); a host
    frame while another command waits is overlapping-command (docs/protocol.md "Behaviour the vendor text
    states"). The discarded command needs no answer."""
    recs = run([(0, H, b"0MP0\r\n"), (0.5, H, b"0RC\r\n"), (2.0, D, b"0MP00002000000\r\n"),
                (3.0, H, b"0RV\r\n"), (3.0, H, b"0RS\r\n"), (3.01, D, b"0RV100\r\n"), (3.02, D, b"0RS02\r\n"),
                (3.1, H, b"0RC\r\n"), (3.11, D, b"0RC00002000000\r\n")])
    assert codes(recs) == [(H, ("command-during-motion",)), (H, ("overlapping-command",))]
    assert recs[-1].reply_to == recs[-2].i


def test_storm_after_fifth_comm_error():
    """After the 5th 0%%01 answer in a row (latched repeats count, a reset answer does not end the run)
    any further command is comm-error-storm but the host's own reset and its first command after 0%C00
    (the notice storm-recovery); a normal answer ends the run (docs/protocol.md "Behaviour the vendor
    text states")."""
    script = []
    t = 0.0
    for _ in range(3):
        script += [(t, H, b"0RP0\r\n"), (t + 0.01, D, b"0%%01\r\n"), (t + 0.1, H, b"0%C\r\n"),
                   (t + 0.11, D, b"0%C00\r\n")]
        t += 0.2
    script += [(t, H, b"0RV\r\n"), (t + 0.01, D, b"0%%01\r\n"), (t + 0.1, H, b"0RV\r\n"),
               (t + 0.11, D, b"0%%01\r\n"), (t + 0.2, H, b"0%C\r\n"), (t + 0.21, D, b"0%C00\r\n"),
               (t + 0.3, H, b"0RV\r\n"), (t + 0.31, D, b"0RV100\r\n"), (t + 0.4, H, b"0RV\r\n"),
               (t + 0.41, D, b"0RV100\r\n")]
    recs = run(script)
    host = [(r.raw, r.violations) for r in recs if r.dir == H and r.violations]
    # 0RP0 is field-range (N 1-F); the 4th 0RV is sent after 5 comm errors, so is the 0%C and the next 0RV
    assert host[:3] == [(b"0RP0\r\n", ("field-range",))] * 3
    assert host[3:] == [(b"0RV\r\n", ("alarm-ignored",)), (b"0%C\r\n", ("storm-recovery",)),
                        (b"0RV\r\n", ("storm-recovery",))]
    assert all_codes([r for r in recs if r.dir == D]) == []


def test_latch_broken_and_estop_recovery_seen_from_the_line():
    """A normal answer while a non-estop alarm is latched is latch-broken. 0%C00 after emergency stop is a
    normal recovery on the line alone: the release of the stop input cannot be seen, so estop-cleared is
    never judged from the line (docs/protocol.md silent item 3); nor is a normal answer under 0E."""
    recs = run([(0, H, b"0RV\r\n"), (0.01, D, b"0%%08\r\n"), (0.1, H, b"0RV\r\n"), (0.11, D, b"0RV100\r\n"),
                (0.2, H, b"0%C\r\n"), (0.21, D, b"0%C00\r\n"), (0.3, H, b"0RV\r\n"), (0.31, D, b"0%%0E\r\n"),
                (0.4, H, b"0%C\r\n"), (0.41, D, b"0%C00\r\n"),
                (0.5, H, b"0RV\r\n"), (0.51, D, b"0%%0E\r\n"), (0.6, H, b"0%C\r\n"), (0.61, D, b"0%%0E\r\n"),
                (0.7, H, b"0RV\r\n"), (0.71, D, b"0RV100\r\n"),
                (0.8, H, b"0RV\r\n"), (0.81, D, b"0RV100\r\n")])
    assert codes(recs) == [(H, ("alarm-ignored",)), (D, ("latch-broken",))]


def test_junk_lines_and_noise():
    """Bytes that form no frame are garbage; a junk line (ending in LF) is an error the device must answer
    with an alarm answer (docs/protocol.md "Behaviour the vendor text states"), silence is no-answer;
    noise before a frame is its own junk."""
    recs = run([(0, H, b"\xff\xfe\r\n"), (0.01, D, b"0%%01\r\n"), (0.1, H, b"\x00\x00"),
                (0.1, H, b"0%C\r\n"), (0.11, D, b"0%C00\r\n"), (0.2, H, b"hello\r\n"),
                (1.3, H, b"0RV\r\n"), (1.31, D, b"0RV100\r\n")])
    assert [(type(r).__name__, r.violations) for r in recs] == [
        ("JunkRecord", ("garbage",)), ("FrameRecord", ()), ("JunkRecord", ("garbage",)),
        ("FrameRecord", ()), ("FrameRecord", ()), ("JunkRecord", ("garbage",)),
        ("TimeoutRecord", ("no-answer",)), ("FrameRecord", ()), ("FrameRecord", ())]
    assert recs[1].reply_to == 0 and recs[6].command == 5 and recs[8].reply_to == 6
    assert recs[6].sides == ("device",) and recs[5].sides == ("host",)


def test_malformed_command_left_unanswered_is_no_answer():
    """A malformed command is owed an alarm answer (docs/protocol.md "Behaviour the vendor text states";
    only its code is silent, item 1): silence is no-answer, and the next command pairs with the next
    answer."""
    recs = run([(0, H, b"0RP\r\n"), (2.0, H, b"0RV\r\n"), (2.01, D, b"0%%01\r\n")])
    assert codes(recs) == [(H, ("bad-length",)), ("timeout", ("no-answer",))]
    assert recs[-1].reply_to == 1


def test_line_errors_go_on_the_record_holding_the_bytes():
    """A capture tool's line error is reported on each record holding a flagged byte, outside violations."""
    a = Analyzer()
    recs = a.feed(Chunk(0, H, b"0RV\r\n0R", "framing error")) + a.feed(Chunk(0.001, H, b"C\r\n"))
    recs += a.feed(Chunk(0.01, D, b"0RV100\r\n")) + a.close()
    assert [r.line_errors for r in recs if isinstance(r, FrameRecord)] == [("framing error",)] * 2 + [()]
    assert a.summary()["line_errors"] == 2


CONVERSATION = [
    (H, b"0RP3\r\n", 0.0), (D, b"0RP39302012345\r\n", 0.01), (H, b"ORP3\r\n", 0.1), (D, b"0%%01\r\n", 0.11),
    (H, b"0RV\r\n0RV\r\n", 0.2), (D, b"0%%01\r\n\xff0%%01\r\n", 0.21), (H, b"0%C\r\n", 0.3),
    (D, b"0%C00\r\n", 0.31), (H, b"0MP0\r\n", 0.4), (H, b"0RC\r\n", 0.5), (D, b"0MP00002000000\r\n", 0.9),
    (H, b"0WS12\r\n", 1.0), (D, b"0WS02\r\n", 1.01), (H, b"zz\r\n", 1.1), (H, b"0RV\r\n", 1.2),
]


def _split(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts} | {0, len(data)})
    return [data[a:b] for a, b in zip(points, points[1:], strict=False) if b > a]


@settings(max_examples=budget(40), deadline=None)
@given(cuts=st.lists(st.lists(st.integers(0, 40), max_size=6), min_size=len(CONVERSATION),
                     max_size=len(CONVERSATION)), timed=st.booleans())
def test_chunking_never_changes_records(cuts, timed):
    """Feeding each stretch of bytes whole, byte by byte or in any chunks gives the same records (the
    framer decides on bytes only; time is per stretch here so latency cannot change either)."""
    whole = [Chunk(t if timed else None, d, b) for d, b, t in CONVERSATION]
    split = [Chunk(t if timed else None, d, part) for (d, b, t), c in zip(CONVERSATION, cuts, strict=True)
             for part in _split(b, c)]
    assert [r.to_json() for r in analyze(whole)] == [r.to_json() for r in analyze(split)]


@settings(max_examples=budget(60), deadline=None)
@given(st.lists(st.tuples(st.sampled_from([H, D]),
                          st.one_of(st.binary(max_size=30), frames().map(lambda f: f.to_bytes())),
                          st.floats(0, 0.5)), max_size=25))
def test_garbage_never_crashes_and_every_byte_is_accounted(items):
    """Arbitrary bytes in both directions never raise; every byte fed comes out in exactly one frame or
    junk record of its direction, in order (docs/protocol.md "Violation codes": garbage)."""
    t = 0.0
    chunks = []
    for d, data, dt in items:
        t += dt
        chunks.append(Chunk(t, d, data))
    recs = analyze(chunks)
    for d in (H, D):
        fed = b"".join(c.data for c in chunks if c.dir == d)
        out = b"".join(r.raw for r in recs if isinstance(r, (FrameRecord, JunkRecord)) and r.dir == d)
        assert out == fed
    assert [r.i for r in recs if not isinstance(r, TimeoutRecord)] == list(range(
        sum(1 for r in recs if not isinstance(r, TimeoutRecord))))
    for r in recs:
        json.loads(r.to_json())


def test_causal_order_puts_answers_after_their_commands():
    """Two taps deliver with different delays: an answer read before its command is held until the
    command comes, a next command read before the previous answer is held until that answer, and a
    held chunk goes out as it is when its window passes (sniffer/order.py)."""
    from sniffer.order import CausalOrder

    a = Analyzer()
    fed: list[Chunk] = []

    def sink(chunk):
        fed.append(chunk)
        a.feed(chunk)

    order = CausalOrder(sink, lambda: a.waiting, lambda: a.expecting_answer, window=0.1)
    order.push(Chunk(1.0, D, b"0RV100\r\n"), now=0.0)  # answer first: held
    assert fed == []
    order.push(Chunk(1.001, H, b"0RV\r\n"), now=0.001)
    assert [c.dir for c in fed] == [H, D] and fed[1].t == 1.001  # times only move forward
    order.push(Chunk(1.01, H, b"0RS\r\n"), now=0.01)
    order.push(Chunk(1.02, H, b"0RV\r\n"), now=0.02)  # next command before the answer: held
    order.push(Chunk(1.02, D, b"0RS02\r\n"), now=0.02)
    assert [c.data for c in fed[2:]] == [b"0RS\r\n", b"0RS02\r\n", b"0RV\r\n"]
    order.push(Chunk(2.0, D, b"0RV100\r\n0RV100\r\n"), now=1.0)  # the second answer has no command
    assert len(fed) == 6
    order.due(now=1.05)
    assert len(fed) == 6
    order.due(now=1.2)
    assert len(fed) == 7 and fed[-1].data == b"0RV100\r\n"


@given(st.lists(st.floats(0, 30, allow_nan=False), min_size=1, max_size=60))
def test_latency_stats_match_exact_statistics_to_the_microsecond(values):
    """The summary's latency min/median/max (bounded memory) equal the exact ones at 1 us resolution."""
    import statistics

    from sniffer.records import LatencyStats

    stats = LatencyStats()
    for v in values:
        stats.add(v)
    us = [round(v * 1e6) for v in values]
    got = stats.stats_ms()
    assert got["n"] == len(values)
    assert got["min"] == min(us) / 1000 and got["max"] == max(us) / 1000
    assert got["median"] == round(statistics.median(us) / 1000, 3)


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True) | st.floats(0, 30), max_size=60),
       st.lists(st.integers(1, 20), max_size=10))
def test_latency_stats_in_batches_count_exactly_the_sane_latencies(values, cuts):
    """``LatencyStats.extend`` (the tally adds a batch at a time) counts the same as adding one latency at
    a time: a damaged one (NaN, infinite, absurd) anywhere in a batch is left out, alone."""
    from sniffer.records import LatencyStats

    one, batched = LatencyStats(), LatencyStats()
    for v in values:
        one.add(v)
    at = 0
    for n in [*cuts, len(values)]:
        batched.extend(values[at:at + n])
        at += n
    sane = [v for v in values if -1e6 <= v <= 1e6]
    assert one.n == batched.n == len(sane)
    if sane:
        assert one.stats_ms() == batched.stats_ms()


# ---- regression tests of issue 12, each named after the rule ----

def test_pairing_resyncs_after_a_device_silent_to_malformed_commands():
    """A device that never answers malformed commands gets no-answer for each, and every later answer
    still pairs with its own command (no answer-mismatch, no overlap pile-up, true latencies)."""
    script, t = [], 0.0
    for _ in range(20):
        script += [(t, H, b"0RP\r\n"), (t + 1.2, H, b"0RV\r\n"), (t + 1.201, D, b"0RV100\r\n")]
        t += 2.0
    recs = run(script)
    assert all_codes(recs) == sorted(["bad-length"] * 20 + ["no-answer"] * 20)
    answers = [r for r in recs if isinstance(r, FrameRecord) and r.dir == D]
    assert all(r.latency_ms is not None and r.latency_ms < 2 for r in answers)


def test_pairing_resyncs_after_a_garbled_answer():
    """One garbled byte in an answer (noise) makes that answer junk inside its command's window: it is the
    command's garbled answer, and later answers pair with their own commands."""
    recs = run([(0, H, b"0RV\r\n"), (0.002, D, b"\xb0RV100\r\n"), (0.1, H, b"0RS\r\n"),
                (0.102, D, b"0RS02\r\n"), (0.2, H, b"0RC\r\n"), (0.202, D, b"0RC00002FFFFFF\r\n")])
    assert codes(recs) == [(D, ("garbage",))]
    junk = recs[1]
    assert isinstance(junk, JunkRecord) and junk.reply_to == 0 and junk.sides == ("device",)
    assert json.loads(junk.to_json())["reply_to"] == 0
    assert [r.reply_to for r in recs if isinstance(r, FrameRecord) and r.dir == D] == [2, 4]


def test_sides_in_records_and_summary_by_side():
    """Each record says whose fault each violation is ("sides", aligned with "violations"); the summary
    counts by side, and the text views show it (docs/protocol.md "Violation codes")."""
    a = Analyzer()
    recs = []
    for t, d, b in [(0, H, b"ORV\r\n"), (0.01, D, b"0%%01\r\n"), (0.1, H, b"O%C\r\n"),
                    (0.11, D, b"0%%01\r\n"), (0.2, H, b"0%C\r\n"), (0.21, D, b"0%C00\r\n"),
                    (0.3, H, b"0RV\r\n"), (0.31, D, b"ORV100\r\n")]:
        recs += a.feed(Chunk(t, d, b))
    recs += a.close()
    assert [json.loads(r.to_json())["sides"] for r in recs if r.violations] == [
        ["host"], ["host", "host"], ["device"]]  # O%C is no reset: alarm-ignored too
    # each violation's severity: an answer's letter O is our reading, a notice (issue 35, verdict 9)
    assert [json.loads(r.to_json())["severities"] for r in recs if r.violations] == [
        ["error"], ["error", "notice"], ["notice"]]
    summary = a.summary()
    assert summary["violations"]["letter-o"] == 3
    assert summary["by_side"] == {"host": {"letter-o": 2, "alarm-ignored": 1}, "device": {"letter-o": 1}}
    from sniffer.view import summary_lines, violation_lines
    assert any("letter-o[/] x3 (host 2, device 1)" in line for line in summary_lines(summary))
    assert "host   ✗ letter-o" in violation_lines(recs[0])[0]
    assert "device ! letter-o" in violation_lines(recs[-1])[0]  # a notice (was ✗ before issue 35)


# ---- one path: feed, feed_many with records, feed_many counting only ----

from test_decode_equivalence import chunks_of, cuts, events, gaps, line_error_at  # noqa: E402


@settings(max_examples=budget(60), deadline=None)
@given(events, gaps, cuts, st.booleans(), line_error_at, st.integers(1, 7))
def test_records_are_made_only_where_wanted_and_change_nothing(items, dts, sizes, timed, flagged, limit):
    """One path from chunks to verdicts: ``feed`` chunk by chunk, ``feed_many`` in batches of any size
    with records, and ``feed_many`` counting only (no records: ``xac1 decode --format summary``) give
    the same summary; the first two the same records, and the summary is what the records count."""
    from sniffer.records import Tally

    chunks = chunks_of(items, dts, sizes, timed, flagged)
    one = Analyzer()
    records = [r for chunk in chunks for r in one.feed(chunk)] + one.close()
    many, counting = Analyzer(), Analyzer()
    batched: list = []
    it = iter(chunks)
    while many.feed_many(it, batched, limit=limit):
        pass
    batched += many.close()
    it = iter(chunks)
    while counting.feed_many(it, None, limit=limit):
        pass
    ended = counting.close()
    assert ended == records[len(records) - len(ended):]  # the end's records, as the others gave them
    tally = Tally()
    for record in records:
        tally.add(record)
    tally.unanswered = one.tally.unanswered
    assert batched == records
    assert one.summary() == many.summary() == counting.summary() == tally.summary()


def test_close_of_a_counting_analyzer_counts_its_verdicts():
    """The records ``close`` makes (a line left unanswered at the end) are counted like any other: the
    summary of an analyzer that made no records before is the same as one that did."""
    script = [(1.0, H, b"0RP3\r\n"), (1.002, D, b"0RP39302012345\r\n"), (1.01, H, b"0RV\r\n")]
    chunks = [Chunk(t, d, b) for t, d, b in script]
    counting, feeding = Analyzer(), Analyzer()
    assert counting.feed_many(iter(chunks)) == 3
    for chunk in chunks:
        feeding.feed(chunk)
    assert [r.type for r in counting.close(5.0)] == [r.type for r in feeding.close(5.0)] == ["timeout"]
    assert counting.summary() == feeding.summary()
    assert counting.summary()["violations"] == {"no-answer": 1}


@pytest.mark.parametrize("data", [b"0RV\r\n", b"0R", b""])
def test_a_chunk_of_no_known_direction_is_a_clear_error(data):
    """A chunk whose direction is neither ``host`` nor ``device`` is a ``ValueError`` naming it, whether
    its bytes are one whole frame (the usual chunk), part of one or none; the chunks before it are
    judged and counted."""
    analyzer = Analyzer()
    good = Chunk(1.0, "host", b"0RV\r\n")
    with pytest.raises(ValueError, match="'sideways'"):
        analyzer.feed_many(iter([good, Chunk(1.1, "sideways", data)]), [])  # type: ignore[arg-type]
    assert analyzer.summary()["commands"] == {"0RV": 1}


def test_a_line_error_is_counted_once_for_an_answer_that_shows_earlier_lines_unanswered():
    """A device frame with a UART error on its bytes that answers the last of three waiting commands also
    gives the first its ``no-answer`` verdict; the summary counts one record with a line error (a missed
    answer has no bytes), whether the analyzer makes records or only counts. Found by hypothesis."""
    chunks = [Chunk(0.001 * k, H, line) for k, line in enumerate((b"0RV\r\n", b"0RS\r\n", b"0RP3\r\n"))]
    chunks.append(Chunk(0.01, D, b"0RP39302012345\r\n", "UART framing error"))
    counting = Analyzer()
    counting.feed_many(iter(chunks), None)
    recs = analyze(chunks)
    assert [r.type for r in recs].count("timeout") == 1
    assert sum(1 for r in recs if r.type != "timeout" and r.line_errors) == 1
    assert counting.summary()["line_errors"] == 1


def test_a_window_that_closed_before_the_answer_began_is_closed_however_the_answer_is_cut():
    """Behind a move still within its window, an overlapped 0RP whose window closed before the answer
    began is closed when the answer begins, whether the answer comes whole or byte by byte: the answer
    pairs with the later 0RP that still waits (found by hypothesis: whole, it paired with the closed one)."""
    t0 = 1_790_000_000.0
    script = [(t0, H, b"0RP3\r\n"), (t0, H, b"0MV3C3001000\r\n"), (t0 + 0.001, H, b"0RP3\r\n"),
              (t0 + 1.001, H, b"0RP3\r\n"), (t0 + 1.002, D, b"0RP39302012345\r\n")]
    whole = [Chunk(t, d, b) for t, d, b in script]
    bytewise = [Chunk(t, d, b[k:k + 1]) for t, d, b in script for k in range(len(b))]
    answers = [[r for r in analyze(chunks) if isinstance(r, FrameRecord) and r.dir == D]
               for chunks in (whole, bytewise)]
    assert [r.reply_to for r in answers[0]] == [r.reply_to for r in answers[1]] == [3]
