"""The sans-IO replay core (``xac1_proto.replay``): the script built from a judged capture, its pacing,
the comparison of answers by kind and by fields, and the device side's matching (docs/replay.md)."""

from __future__ import annotations

import pytest
from conftest import CAPTURES, budget
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

from sniffer.analyzer import Analyzer
from sniffer.io.registry import Capture, detect
from sniffer.records import FrameRecord, JunkRecord
from sniffer.replay_script import add_records, read_script, script_of
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.codec import diagnose
from xac1_proto.frames import AlarmAnswer, Frame, ReadOutputsAnswer, ReadPointAnswer, ReadVersionAnswer
from xac1_proto.replay import (
    ALARM_INSTEAD,
    ANSWER_INSTEAD,
    BYTES,
    EXTRA,
    HEADER,
    MISSING,
    Answer,
    ScriptBuilder,
    ScriptCursor,
    compare,
)


def answer(frame_or_raw: Frame | bytes, t: float | None = None) -> Answer:
    """An answer as the engine reads it: the lenient decode of its bytes."""
    raw = frame_or_raw if isinstance(frame_or_raw, bytes) else frame_or_raw.to_bytes()
    frame, _ = diagnose(raw, spec.ANSWER)
    header = frame.header if frame is not None else None
    return Answer(raw, header, frame, t, None if t is None else t + len(raw) * spec.BYTE_TIME_S)


# ---- the comparison ----

@settings(max_examples=budget(60))
@given(frames(spec.ANSWER))
def test_an_answer_compared_with_itself_is_the_same(frame):
    """The same answer bytes are the same, whatever the frame."""
    a = answer(frame)
    assert compare([a], [answer(frame)]).same


@settings(max_examples=budget(80))
@given(frames(spec.ANSWER), frames(spec.ANSWER))
def test_two_answers_differ_by_kind_or_by_the_fields_that_differ(e, g):
    """Two answers: same iff their bytes are; an alarm for a normal answer (or the reverse) is named as
    such; answers of two commands are ``header``; else exactly the fields whose values differ."""
    result = compare([answer(e)], [answer(g)]).differences
    if e.to_bytes() == g.to_bytes():
        assert result == ()
    elif isinstance(e, AlarmAnswer) != isinstance(g, AlarmAnswer):
        assert result == ((ALARM_INSTEAD,) if isinstance(g, AlarmAnswer) else (ANSWER_INSTEAD,))
    elif type(e) is not type(g):
        assert result == (HEADER,)
    else:
        fe, fg = e.fields(), g.fields()
        assert result == tuple(n for n in fe if fe[n] != fg[n])


@pytest.mark.parametrize(("expected", "got", "differences"), [
    ([b"0RV100\r\n"], [], (MISSING,)),
    ([], [b"0RV100\r\n"], (EXTRA,)),
    ([], [], ()),
    ([b"0RV100\r\n"], [b"0RV100\r\n", b"0RV100\r\n"], (EXTRA,)),
    ([b"0RP19302012345\n"], [b"0RP19302012345\r\n"], (BYTES,)),  # a framing difference, same fields
    ([b"0RS02\r\n"], [b"\x00\xff\r\n"], (BYTES,)),  # a garbled answer: bytes only
    ([b"0RS02\r\n"], [b"0%%01\r\n"], (ALARM_INSTEAD,)),
    ([b"0%%01\r\n"], [b"0RS02\r\n"], (ANSWER_INSTEAD,)),
    ([b"0%%01\r\n"], [b"0%%0E\r\n"], ("code",)),
    ([b"0RS02\r\n"], [b"0RV100\r\n"], (HEADER,)),
    ([b"0RP19302012345\r\n"], [b"0RP28302012346\r\n"], ("n", "v", "pos")),
])
def test_answer_kinds_named(expected, got, differences):
    """Each kind of difference of docs/replay.md is named, and only it."""
    assert compare([answer(r) for r in expected], [answer(r) for r in got]).differences == differences


# ---- the script ----

lines_strategy = st.lists(st.tuples(
    st.sampled_from([b"0RV\r\n", b"0RS\r\n", b"ORP1\r\n", b"0rs\r\n", b"\x00~", b"0RP3\r\n"]),
    st.floats(0.0, 2.0),  # gap before the line
    st.lists(st.sampled_from([ReadVersionAnswer(version="100"), ReadOutputsAnswer(o=2),
                              AlarmAnswer(code=1), ReadPointAnswer(n=3, v=1, a=1, o=0, pos=5)]),
             max_size=2),
    st.floats(0.0, 0.05)), min_size=1, max_size=12)


@settings(max_examples=budget(60))
@given(lines_strategy)
def test_script_keeps_every_line_its_answers_and_their_timing(conversation):
    """Every host line is kept in order, byte for byte, with the answers paired with it, the same bytes
    as its replies (they came before the next line) with each one's delay after the line's last byte; a
    line sent after the previous answer ended gets the gap from that answer's end."""
    builder = ScriptBuilder()
    t = 100.0
    expected = []
    for host_i, (raw, gap, answers, delay) in enumerate(conversation):
        t += gap
        t_last = t + len(raw) * spec.BYTE_TIME_S
        builder.host(host_i, raw, t, t_last)
        at = t_last + delay
        made = []
        for frame in answers:
            a = answer(frame, at)
            builder.device(a, host_i)
            made.append((a, at - t_last))
            at = a.t_last + delay
        expected.append((raw, t, made))
        t = at
    script = builder.build()
    assert [line.raw for line in script.lines] == [raw for raw, _, _ in expected]
    for line, (_, _, made) in zip(script.lines, expected, strict=True):
        assert line.answers == tuple(a for a, _ in made)
        assert [a for a, _ in line.replies] == [a for a, _ in made]
        assert [d for _, d in line.replies] == pytest.approx([d for _, d in made])
    for before, line in zip(script.lines, script.lines[1:], strict=False):
        assert line.after_answer == bool(before.answers)
        if line.after_answer:
            assert line.gap_s == pytest.approx(line.t - before.answers[-1].t_last)
        else:
            assert line.gap_s == pytest.approx(line.t - before.t)


def test_an_overlap_is_kept_as_an_overlap():
    """A line sent before the previous line's answer came is not ``after_answer``: it goes at its gap
    after the previous line, not after an answer."""
    builder = ScriptBuilder()
    builder.host(0, b"0RV\r\n", 1.0, 1.005)
    builder.host(1, b"0RS\r\n", 1.006, 1.011)
    builder.device(answer(b"0RV100\r\n", 1.02), 0)
    builder.device(answer(b"0RS02\r\n", 1.03), 1)
    first, second = builder.build().lines
    assert not second.after_answer and second.gap_s == pytest.approx(0.006)
    assert [a.raw for a in first.answers] == [b"0RV100\r\n"]


def test_a_late_answer_is_replied_after_the_line_it_followed():
    """An answer the engine paired with a line but that came only after the next line was sent is that
    line's answer (for the comparison) and the next line's reply (the device side keeps the captured
    timeline: the host meets it after its second line, as it did)."""
    builder = ScriptBuilder()
    builder.host(0, b"0XX\r\n", 1.0, 1.005)
    builder.host(1, b"0RS\r\n", 1.4, 1.405)
    builder.device(answer(b"0%%01\r\n", 1.41), 0)
    first, second = builder.build().lines
    assert [a.raw for a in first.answers] == [b"0%%01\r\n"] and first.replies == ()
    assert second.answers == () and [(a.raw, d) for a, d in second.replies] == [
        (b"0%%01\r\n", pytest.approx(0.005))]


def test_without_time_the_replies_are_the_answers():
    """A capture without time (raw files): the device side replies with the engine's pairing."""
    builder = ScriptBuilder()
    builder.host(0, b"0RV\r\n")
    builder.device(answer(b"0RV100\r\n"), 0)
    (line,) = builder.build().lines
    assert line.replies == ((line.answers[0], None),)


def test_unpaired_device_bytes_go_to_the_last_line_sent_before_them():
    """Device bytes the engine paired with no line belong to the last host line before them (a late
    answer stays late); those before any line are the script's lead."""
    builder = ScriptBuilder()
    builder.device(answer(b"0RV100\r\n", 0.5))
    builder.host(0, b"0RV\r\n", 1.0, 1.005)
    builder.host(1, b"0RS\r\n", 2.0, 2.005)
    builder.device(answer(b"0RV100\r\n", 2.1))
    script = builder.build()
    assert [a.raw for a in script.lead] == [b"0RV100\r\n"]
    assert script.lines[0].answers == ()
    assert [a.raw for a in script.lines[1].answers] == [b"0RV100\r\n"]


_COMMANDS = [b"0RV\r\n", b"0RS\r\n", b"0RP1\r\n", b"0RC\r\n", b"0XX\r\n", b"0R", b"\x000RV\r\n"]
_ANSWERS = [b"0RV100\r\n", b"0RS02\r\n", b"0%%01\r\n", b"0RC0000200123A\r\n", b"zz", b"0RV1"]


@settings(max_examples=budget(200), deadline=None)
@given(st.lists(st.tuples(st.sampled_from(_COMMANDS), st.lists(st.sampled_from(_ANSWERS), max_size=2),
                          st.sampled_from([0.0, 0.004, 0.02, 0.3, 1.2]),
                          st.sampled_from([0.0, 0.01, 0.5, 2.5]), st.booleans()),
                max_size=14),
       st.booleans())
def test_a_script_handed_out_as_it_settles_equals_the_whole(exchanges, timed):
    """``ScriptBuilder.settled()``, asked whenever the conversation is quiet (no answer awaited, every
    device byte framed: what ``ScriptStream`` does to read a capture of any size in flat memory), hands
    out the very lines ``build()`` makes from the whole capture, answers, replies and pacing included:
    overlaps, late and missing answers, line noise, answers in pieces, with and without time."""
    chunks, t = [], 1000.0
    for command, answers, delay, gap, split in exchanges:
        chunks.append(Chunk(t if timed else None, HOST, command))
        at = t + delay
        for a in answers:
            parts = [a[:2], a[2:]] if split and len(a) > 2 else [a]
            for part in parts:
                chunks.append(Chunk(at if timed else None, DEVICE, part))
                at += 0.003
        t = at + gap
    analyzer, streamed, whole, device_framed = Analyzer(), ScriptBuilder(), [], 0
    lines = []
    for chunk in chunks:
        records = analyzer.feed(chunk)
        whole += records
        device_framed += add_records(streamed, records)
        if not analyzer.waiting and device_framed == analyzer.bytes_in(DEVICE):
            lines += streamed.settled()
    records = analyzer.close()
    whole += records
    add_records(streamed, records)
    lines += streamed.finish()
    assert tuple(lines) == script_of(whole).lines
    assert streamed.lead == script_of(whole).lead


GALLERY = sorted(p.name for p in CAPTURES.iterdir() if p.suffix in (".log", ".txt", ".jsonl", ".pcap",
                                                                    ".pcapng", ".csv", ".bin"))


@pytest.mark.parametrize("name", [n for n in GALLERY if "device" not in n and "glitch" not in n])
def test_every_gallery_capture_reads_as_the_decode_pairs_it(name):
    """Each gallery capture read as a script holds exactly its host bytes as lines and every device
    record under the line the analyzer paired it with (``xac1 decode``'s reading)."""
    captured = read_script([str(CAPTURES / name)])
    path = str(CAPTURES / name)
    fmt = detect([path]).name
    files = [path, path.replace("host", "device")] if fmt in ("raw", "saleae") and "host" in name else [path]
    with Capture(files, fmt) as capture:
        analyzer = Analyzer()
        records = [r for chunk in capture for r in analyzer.feed(chunk)] + analyzer.close()
    host = [r for r in records if isinstance(r, (FrameRecord, JunkRecord)) and r.dir == "host"]
    assert [line.raw for line in captured.script.lines] == [r.raw for r in host]
    assert [line.i for line in captured.script.lines] == [r.i for r in host]
    by_line = {r.i: [] for r in host}
    for r in records:
        if isinstance(r, (FrameRecord, JunkRecord)) and r.dir == "device" and r.reply_to is not None:
            by_line[r.reply_to].append(r.raw)
    for line in captured.script.lines:
        paired = by_line[line.i]
        assert [a.raw for a in line.answers][: len(paired)] == paired
    assert script_of(records).lines == captured.script.lines


# ---- the device side's matching ----

def _script(*lines: tuple[bytes, list[bytes]]):
    builder = ScriptBuilder()
    t, i = 0.0, 0
    for raw, answers in lines:
        builder.host(i, raw, t, t + 0.005)
        host_i = i
        i += 1
        for a in answers:
            builder.device(answer(a, t + 0.01), host_i)
            i += 1
        t += 1.0
    return builder.build()


@settings(max_examples=budget(60))
@given(st.lists(st.sampled_from([b"0RV\r\n", b"0RS\r\n", b"0RP1\r\n", b"0RC\r\n"]), min_size=1, max_size=10),
       st.data())
def test_a_host_that_repeats_lines_still_lines_up(lines, data):
    """Played in order, every captured line matches with none passed over; a line sent again (a retry)
    matches the next captured line equal to it, passing over the lines between."""
    script = _script(*[(raw, [b"0RV100\r\n"]) for raw in lines])
    cursor = ScriptCursor(script)
    for n, raw in enumerate(lines):
        match = cursor.match(raw)
        assert match is not None and match.lines[0].n == n and match.skipped == 0
    assert cursor.done
    cursor = ScriptCursor(script)
    k = data.draw(st.integers(0, len(lines) - 1))
    match = cursor.match(lines[k])
    first = lines.index(lines[k])
    assert match is not None and match.lines[0].n == first and match.skipped == first


def test_a_line_not_in_the_rest_of_the_capture_leaves_the_cursor():
    """A line the capture does not hold next is not matched (counted); the cursor stays where it was."""
    cursor = ScriptCursor(_script((b"0RV\r\n", [b"0RV100\r\n"]), (b"0RS\r\n", [b"0RS00\r\n"])))
    assert cursor.match(b"0RS\r\n") is not None and cursor.position == 2
    assert cursor.match(b"0RV\r\n") is None
    assert cursor.position == 2 and cursor.unmatched == 1 and "1 not in the capture" in cursor.where()


def test_noise_and_the_frame_after_it_match_as_one_line():
    """Line noise the capture holds as its own junk run before a frame is matched together with that
    frame (the device side sees one line up to LF); the answers are the frame's."""
    cursor = ScriptCursor(_script((b"\x00~", []), (b"0RV\r\n", [b"0RV100\r\n"])))
    match = cursor.match(b"\x00~0RV\r\n")
    assert match is not None and [line.raw for line in match.lines] == [b"\x00~", b"0RV\r\n"]
    assert [a.raw for a, _ in match.answers] == [b"0RV100\r\n"]
