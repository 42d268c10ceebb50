"""The sans-IO framer: resync, bounds, byte accounting, chunking invariance (docs/protocol.md "Framing")."""

from __future__ import annotations

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

from xac1_proto import FrameBytes, Framer, Junk


def run(stream: bytes, cuts: list[int] | None = None, t: float | None = None):
    """Feed ``stream`` split at ``cuts`` (None: whole), then flush; return the events."""
    framer = Framer()
    events = []
    points = sorted(set(c for c in (cuts or []) if 0 < c < len(stream)))
    prev = 0
    for c in [*points, len(stream)]:
        events += framer.feed(stream[prev:c], t)
        prev = c
    events += framer.flush()
    assert framer.pending == 0
    return events


def shape(events):
    return [(type(e).__name__, e.raw, e.offset, getattr(e, "reason", None)) for e in events]


CASES = [
    # (stream, expected [(kind, raw, reason)])
    (b"0RP3\r\n", [("FrameBytes", b"0RP3\r\n", None)]),
    (b"0RP3\r\n0RV\r\n", [("FrameBytes", b"0RP3\r\n", None), ("FrameBytes", b"0RV\r\n", None)]),
    (b"xyz0RP3\r\n", [("Junk", b"xyz", "no-frame-start"), ("FrameBytes", b"0RP3\r\n", None)]),
    (b"0RP0RP3\r\n", [("Junk", b"0RP", "truncated"), ("FrameBytes", b"0RP3\r\n", None)]),
    (b"ORP3\r\n", [("FrameBytes", b"ORP3\r\n", None)]),
    (b"0rp3\r\n", [("FrameBytes", b"0rp3\r\n", None)]),
    (b"HELLO\r\n0RV\r\n", [("Junk", b"HELLO\r\n", "no-frame-start"), ("FrameBytes", b"0RV\r\n", None)]),
    (b"0RP3\n", [("FrameBytes", b"0RP3\n", None)]),
    (b"0RP39302012345\r\n", [("FrameBytes", b"0RP39302012345\r\n", None)]),
    (b"0RV\r\n\x00\xff", [("FrameBytes", b"0RV\r\n", None), ("Junk", b"\x00\xff", "no-frame-start")]),
    (b"0RP3", [("Junk", b"0RP3", "flushed")]),
    (b"0\r\n0RV\r\n", [("Junk", b"0\r\n", "no-frame-start"), ("FrameBytes", b"0RV\r\n", None)]),
    (b"0" * 100 + b"0RV\r\n", [("Junk", b"0" * 64, "no-frame-start"),
                              ("Junk", b"0" * 36, "no-frame-start"), ("FrameBytes", b"0RV\r\n", None)]),
    (b"0A" + b"1" * 70 + b"\r\n", [("Junk", b"0A" + b"1" * 62, "overflow"),
                                   ("Junk", b"1" * 8 + b"\r\n", "no-frame-start")]),
]


@pytest.mark.parametrize("stream,expected", CASES)
@pytest.mark.parametrize("feeding", ["whole", "bytewise", "trailing"])
def test_cases(stream, expected, feeding):
    """Each case fed whole, byte by byte, and with trailing bytes still pending gives the same events."""
    cuts = list(range(len(stream))) if feeding == "bytewise" else None
    if feeding == "trailing":  # a whole frame after the case: the case's partial frame is cut short
        events = run(stream + b"0RV\r\n")
        assert (type(events[-1]), events[-1].raw) == (FrameBytes, b"0RV\r\n")
        events = events[:-1]
        expected = [(k, raw, "truncated" if why == "flushed" else why) for k, raw, why in expected]
    else:
        events = run(stream, cuts)
    assert [(type(e).__name__, e.raw, getattr(e, "reason", None)) for e in events] == expected


def test_timestamps_are_those_of_first_and_last_byte():
    """A frame's times are those of the chunks holding its first and its last byte."""
    framer = Framer()
    assert framer.feed(b"0R", 1.0) == []
    assert framer.feed(b"P3\r", 2.0) == []
    (ev,) = framer.feed(b"\n0R", 3.0)
    assert isinstance(ev, FrameBytes) and (ev.t_first, ev.t_last) == (1.0, 3.0)
    (junk,) = framer.flush()
    assert isinstance(junk, Junk) and (junk.t_first, junk.t_last, junk.offset) == (3.0, 3.0, 6)


def test_buffer_is_bounded():
    """A stream with no LF never grows the framer's pending bytes past one frame's limit and a chunk."""
    framer = Framer()
    for _ in range(1000):
        framer.feed(b"0A12345678")
        assert framer.pending < 64 + 10


segments = st.one_of(
    frames().map(lambda f: ("frame", f.to_bytes())),
    st.binary(min_size=1, max_size=30).map(lambda b: ("garbage", b)),
)


@settings(max_examples=budget(300))
@given(st.lists(segments, max_size=8), st.lists(st.integers(0, 400), max_size=12))
def test_chunking_never_changes_events_and_every_byte_is_accounted(parts, cuts):
    """Any cutting of a stream gives the same events, and every byte fed is in exactly one event."""
    stream = b"".join(raw for _, raw in parts)
    whole = run(stream)
    assert shape(run(stream, cuts)) == shape(whole)
    assert shape(run(stream, list(range(len(stream))))) == shape(whole)
    # exact accounting: events tile the stream in order
    assert b"".join(e.raw for e in whole) == stream
    at = 0
    for e in whole:
        assert e.offset == at and e.raw
        at += len(e.raw)


@settings(max_examples=budget(300))
@given(st.lists(segments, max_size=8))
def test_no_valid_frame_is_lost_among_garbage(parts):
    """A valid frame that follows any garbage is still found whole (resync on the next header)."""
    stream = b"".join(raw for _, raw in parts)
    found = [e.raw for e in run(stream) if isinstance(e, FrameBytes)]
    wanted = [raw for kind, raw in parts if kind == "frame"]
    it = iter(found)
    assert all(raw in it for raw in wanted), (wanted, found)  # a subsequence, in order


@settings(max_examples=budget(300))
@given(st.lists(segments, min_size=1, max_size=3), st.booleans())
def test_take_frame_decides_as_the_byte_by_byte_framer(parts, as_bytearray):
    """``Framer.take_frame`` (the usual chunk: one whole frame) takes a chunk exactly when the framer fed
    it byte by byte makes one frame event of all of it; the decision is a pure function of the bytes,
    the same for ``bytes`` (remembered) and a ``bytearray``, asked once or twice."""
    chunk = b"".join(raw for _, raw in parts)
    events = run(chunk, list(range(len(chunk))))
    whole = len(events) == 1 and isinstance(events[0], FrameBytes)
    for _ in range(2):
        framer = Framer()
        taken = framer.take_frame(bytearray(chunk) if as_bytearray else chunk)
        assert (taken == 0) == whole and (taken is None) == (not whole)
        assert framer.bytes_in == (len(chunk) if whole else 0) and framer.pending == 0
