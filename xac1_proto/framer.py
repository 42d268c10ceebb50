"""Sans-IO stream framer: bytes in (with a timestamp), frames and junk out (docs/protocol.md "Framing").

A frame starts at a plausible frame start and ends at LF. A plausible start is the digit ``0`` followed
by a header-like byte (a letter or ``%``), or the letter ``O`` followed by a known header's last two
characters (so the lenient decoder can name a host's ``letter-o``). Bytes before a start, lines that do
not start like a frame, a frame start cut short by the next full header (``0RP`` + ``0RP3\\r\\n``), and
runs of ``MAX_FRAME`` bytes with no LF come out as junk. No valid frame contains a full header after
its first byte, so resyncing on one never splits a good frame.

Decisions depend only on the bytes, never on how they were chunked: feeding a stream whole, byte by
byte or in any chunks gives the same events. Every byte fed comes out in exactly one event; ``flush()``
(end of data, or an idle line) turns a partial frame into junk.
"""

from __future__ import annotations

import bisect
import functools
import re
from collections.abc import Callable
from typing import Final, NamedTuple

from . import spec

MAX_FRAME: Final = 64  # bytes a frame may reach without LF before it becomes junk

_TAILS: Final = frozenset(h[1:].encode() for hs in spec.HEADERS.values() for h in hs)
_SECOND: Final = frozenset(t[0] for t in _TAILS)
_HEADERISH: Final = frozenset(
    b for b in range(256) if chr(b).isascii() and (chr(b).isalpha() or chr(b) == "%")
)
_ZERO: Final = spec.LEAD[0]
_O: Final = spec.LETTER_O[0]
_LF: Final = spec.LF
_UNDECIDED: Final = -2
_START_BYTE: Final = re.compile(b"[" + re.escape(spec.LEAD + spec.LETTER_O) + b"]")
assert all(len(t) == 2 for t in _TAILS), "a full header is a start byte and a two-byte tail"
# a full header (what ``_strong_start`` calls 1), as one pattern: one C-level search per frame
_STRONG: Final = re.compile(_START_BYTE.pattern + b"(?:" + b"|".join(re.escape(t) for t in sorted(_TAILS))
                            + b")")


class FrameBytes(NamedTuple):
    """A candidate frame: from a frame start to its LF. ``offset`` counts bytes fed before it."""

    raw: bytes
    offset: int
    t_first: float | None
    t_last: float | None


class Junk(NamedTuple):
    """Bytes that form no frame, and why: ``no-frame-start``, ``truncated``, ``overflow``,
    ``flushed``."""

    raw: bytes
    offset: int
    t_first: float | None
    t_last: float | None
    reason: str


Event = FrameBytes | Junk


@functools.cache
def _line_pattern(max_frame: int) -> re.Pattern[bytes]:
    """A frame start (``0`` + a letter or ``%``, or ``O`` + a known tail), then bytes other than LF, then
    the LF, ``max_frame`` bytes at most: a whole line that starts like a frame (``Framer.take_frame``; it
    is one frame when no full header starts after its first byte, ``_STRONG``)."""
    tails = b"(?:" + b"|".join(re.escape(t) for t in sorted(_TAILS)) + b")"
    lead, letter_o = re.escape(spec.LEAD), re.escape(spec.LETTER_O)
    start = b"(?:" + lead + b"(?=[A-Za-z%])|" + letter_o + b"(?=" + tails + b"))"
    return re.compile(start + b"[^\n]{0,%d}\n" % (max_frame - 2))


def _is_one_frame(data: bytes, line: Callable[[bytes], re.Match[bytes] | None]) -> bool:
    """Is ``data`` exactly one frame: a whole ``line`` (``_line_pattern``) in which no full header starts
    after the first byte? (With the LF last, no start byte is left undecided.)"""
    return line(data) is not None and _STRONG.search(data, 1) is None


LINE_CACHE: Final = 4096  # distinct lines ``_one_frame_test`` remembers, for each frame length limit


@functools.cache
def _one_frame_test(max_frame: int) -> Callable[[bytes], bool]:
    """``_is_one_frame`` for frames of at most ``max_frame`` bytes, as a pure function of the bytes: the
    last ``LINE_CACHE`` distinct lines are remembered (traffic repeats its lines)."""
    line, strong = _line_pattern(max_frame).fullmatch, _STRONG.search

    @functools.lru_cache(maxsize=LINE_CACHE)
    def one_frame(data: bytes) -> bool:
        return line(data) is not None and strong(data, 1) is None  # (``_is_one_frame``, one call less)

    return one_frame


def _strong_start(buf: bytes | bytearray, p: int) -> int:
    """1 if a full header (``0``/``O`` + known tail) starts at p, 0 if not, _UNDECIDED if the
    buffer ends before that is known."""
    if buf[p] not in (_ZERO, _O):
        return 0
    tail = bytes(buf[p + 1: p + 3])
    if len(tail) == 2:
        return 1 if tail in _TAILS else 0
    if not tail or (tail[0] in _SECOND and any(t.startswith(tail) for t in _TAILS)):
        return _UNDECIDED
    return 0


def _weak_start(buf: bytes | bytearray, p: int) -> int:
    """1 if a frame may start at p (``0`` + a letter or ``%``, or ``O`` + a known tail)."""
    b = buf[p]
    if b == _ZERO:
        if p + 1 >= len(buf):
            return _UNDECIDED
        return 1 if buf[p + 1] in _HEADERISH else 0
    if b == _O:
        return _strong_start(buf, p)
    return 0


class Framer:
    """Split a byte stream into ``FrameBytes`` and ``Junk`` events; see the module docstring."""

    def __init__(self, max_frame: int = MAX_FRAME) -> None:
        if max_frame < 16:
            raise ValueError(f"max_frame must be at least 16 (the longest frame), got {max_frame}")
        self.max_frame = max_frame
        self._buf = bytearray()
        self._base = 0  # stream offset of _buf[0]
        self._ends: list[int] = []  # stream offset just past each fed chunk still in _buf
        self._times: list[float | None] = []
        self._line = _line_pattern(max_frame).fullmatch  # a whole line starting like a frame
        self._one_frame = _one_frame_test(max_frame)

    @property
    def bytes_in(self) -> int:
        """Bytes fed so far."""
        return self._base + len(self._buf)

    @property
    def pending(self) -> int:
        """Bytes fed but not yet in an event."""
        return len(self._buf)

    def take_frame(self, data: bytes) -> int | None:
        """The common chunk: when nothing is pending and ``data`` is exactly one frame (the event ``feed``
        would give), take it and return its stream offset; else None, taking nothing (``feed`` it)."""
        if self._buf:
            return None
        if not (self._one_frame(data) if type(data) is bytes else _is_one_frame(data, self._line)):
            return None  # (a bytearray cannot be remembered)
        offset = self._base
        self._base = offset + len(data)
        return offset

    def feed(self, data: bytes, t: float | None = None) -> list[Event]:
        """Take the next bytes of the stream (all received at time ``t``); the events they complete."""
        offset = self.take_frame(data)
        if offset is not None:
            return [FrameBytes(data if type(data) is bytes else bytes(data), offset, t, t)]
        if data:
            self._buf += data
            self._ends.append(self.bytes_in)
            self._times.append(t)
        return self._drain(final=False)

    def flush(self) -> list[Event]:
        """End of data (or an idle line): what is pending comes out, a partial frame as junk."""
        return self._drain(final=True)

    def _drain(self, final: bool) -> list[Event]:
        out: list[Event] = []
        while self._buf:
            event = self._next(final)
            if event is None:
                break
            out.append(event)
        return out

    def _next(self, final: bool) -> Event | None:
        buf = self._buf
        start = _weak_start(buf, 0)
        if start == _UNDECIDED and not final:
            return None
        if start == 1:
            return self._frame_candidate(final)
        return self._junk_run(final)

    def _frame_candidate(self, final: bool) -> Event | None:
        buf = self._buf
        lf = buf.find(_LF, 0, self.max_frame)
        limit = lf if lf >= 0 else min(len(buf), self.max_frame)
        # the first full header after the start byte and before ``limit`` cuts this frame short; a
        # start byte in the last two bytes of the buffer cannot be decided yet (its tail is not in).
        # Every decidable start comes before every undecided one, so searching the decidable ones
        # first keeps the byte-by-byte order of the rule.
        strong = _STRONG.search(buf, 1, limit + 2)
        if strong is not None:
            return self._emit(strong.start(), "truncated")
        if not final:
            for p in range(max(1, len(buf) - 2), limit):
                if _strong_start(buf, p) == _UNDECIDED:
                    return None
        if lf >= 0:
            return self._emit(lf + 1, None)
        if len(buf) >= self.max_frame:
            return self._emit(self.max_frame, "overflow")
        return self._emit(len(buf), "flushed") if final else None

    def _junk_run(self, final: bool) -> Event | None:
        buf = self._buf
        limit = min(len(buf), self.max_frame)
        for p in range(1, limit):
            if buf[p - 1] == _LF:
                return self._emit(p, "no-frame-start")
            found = _weak_start(buf, p)
            if found == 1:
                return self._emit(p, "no-frame-start")
            if found == _UNDECIDED and not final:
                return None
        if buf[limit - 1] == _LF or len(buf) >= self.max_frame or final:
            return self._emit(limit, "no-frame-start")
        return None

    def _time_at(self, offset: int) -> float | None:
        return self._times[bisect.bisect_right(self._ends, offset)]

    def _emit(self, n: int, reason: str | None) -> Event:
        raw = bytes(self._buf[:n])
        offset = self._base
        t_first, t_last = self._time_at(offset), self._time_at(offset + n - 1)
        del self._buf[:n]
        self._base += n
        drop = bisect.bisect_right(self._ends, self._base)
        del self._ends[:drop], self._times[:drop]
        if reason is None:
            return FrameBytes(raw, offset, t_first, t_last)
        return Junk(raw, offset, t_first, t_last, reason)
