"""Replay of a captured conversation, sans-IO: the script, its pacing, the matching and the comparison.

How it works. A shell reads a capture and has the conversation judged as the sniffer does (the one
rulebook pairs each answer with its host line); it hands the result to ``ScriptBuilder`` one line event
at a time (``host`` for every host frame or junk run, ``device`` for every device frame or junk run, with
the host line it answers when the engine paired it). ``build()`` gives a ``Script``: the host lines in
order, byte for byte (malformed lines and line noise included), each with the device bytes that answered
it (for the comparison), the device bytes that followed it in time and how long after its last byte
they came (for the device side), and how it was paced: sent after the device had answered the previous
line (``after_answer``, ``gap_s`` from the last of those bytes) or not (back to back, an overlap, after
a silence: ``gap_s`` from the previous line's first byte). Device bytes the engine paired
with no line belong to the last line sent before them (a late answer stays late); those before any line
are the script's ``lead``.

Two uses (docs/replay.md):

- the host side played against a device: ``compare`` judges each answer received against the captured
  one by kind and by fields (``SAME``, the differing field names, ``ALARM_INSTEAD``, ``ANSWER_INSTEAD``,
  ``MISSING``, ``EXTRA``, ``HEADER``, ``BYTES``); both sides' frames are the engine's lenient decodes;
- the device side played to host software: ``ScriptCursor.match(line)`` finds the next captured line
  equal to the line received (so a host that repeats or retries still lines up) and gives its answers.

No clock, no port: times come in as numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

from . import spec
from .codec import show_bytes
from .frames import AlarmAnswer, Frame

SAME: Final = "same"
MISSING: Final = "missing"  # the captured device answered, this one did not
EXTRA: Final = "extra"  # this device answered where the captured one stayed silent, or answered more
ALARM_INSTEAD: Final = "alarm-instead-of-answer"
ANSWER_INSTEAD: Final = "answer-instead-of-alarm"
HEADER: Final = "header"  # another command's answer
BYTES: Final = "bytes"  # the same fields (or none readable) in other bytes: a framing difference
KINDS: Final = (MISSING, EXTRA, ALARM_INSTEAD, ANSWER_INSTEAD, HEADER, BYTES)


@dataclass(frozen=True, slots=True)
class Answer:
    """Device bytes answering a host line: a frame or a junk run as the engine read them. ``t``/``t_last``:
    their first and last byte (None without time); ``frame``: the lenient decode (None: unreadable)."""

    raw: bytes
    header: str | None = None
    frame: Frame | None = None
    t: float | None = None
    t_last: float | None = None

    @property
    def alarm(self) -> bool:
        return isinstance(self.frame, AlarmAnswer) or self.header == spec.ALARM_HEADER


@dataclass(frozen=True, slots=True)
class CapturedLine:
    """One host line of the capture and what the device did. ``n``: its place among the host lines;
    ``i``: its record number in the capture (``xac1 decode``'s ``i``); ``answers``: the device bytes the
    engine paired with it (what a replay compares); ``replies``: the device bytes that came after it and
    before the next line, each with its delay from this line's last byte (None without time): what the
    device side sends back, so the host meets the captured timeline (a late answer to an earlier line
    comes after the line it followed); without time, the answers. ``after_answer``/``gap_s``: the pacing
    (module docstring)."""

    n: int
    i: int
    raw: bytes
    t: float | None
    t_last: float | None
    answers: tuple[Answer, ...] = ()
    replies: tuple[tuple[Answer, float | None], ...] = ()
    after_answer: bool = False
    gap_s: float | None = None


@dataclass(frozen=True)
class Script:
    """The capture's host lines with their answers, in order; ``lead``: device bytes before any line."""

    lines: tuple[CapturedLine, ...]
    lead: tuple[Answer, ...] = ()

    def __len__(self) -> int:
        return len(self.lines)


@dataclass
class _Open:
    i: int
    raw: bytes
    t: float | None
    t_last: float | None
    answers: list[Answer] = field(default_factory=list)
    replies: list[Answer] = field(default_factory=list)  # device runs after it by time, before the next


class ScriptBuilder:
    """Collects the capture's judged events in the order seen (module docstring) and hands out the
    script's lines: ``settled()`` as they become final (a capture of any size, line by line), ``build()``
    or ``finish()`` for the rest at the end.

    A line is final once nothing the capture holds further on can belong to it: the caller says when
    (``settled``: the engine waits for no answer and no device bytes are still being framed), and every
    line but the last one seen is then final: no later answer can pair with it, device bytes the engine
    pairs with no line go to the last line, and every device run that began before the last line did
    has been seen. Only the lines since the last such moment are held. Replies are placed by time when
    the capture has time (every line and device run seen so far has one), else by the engine's pairing."""

    def __init__(self) -> None:
        self._lines: list[_Open] = []  # lines not handed out yet, in order
        self._by_i: dict[int, _Open] = {}
        self._lead: list[Answer] = []
        self._timed = True  # every line and device run so far has a time
        self._n = 0  # the place of ``_lines[0]`` among all the capture's lines
        self._before: _Open | None = None  # the last line handed out (the pacing of the next)

    def host(self, i: int, raw: bytes, t: float | None = None, t_last: float | None = None) -> None:
        """A host frame or junk run, record number ``i``."""
        line = _Open(i, bytes(raw), t, t if t_last is None else t_last)
        self._timed = self._timed and t is not None
        self._lines.append(line)
        self._by_i[i] = line

    def device(self, answer: Answer, reply_to: int | None = None) -> None:
        """Device bytes; ``reply_to``: the host line's record number the engine paired them with."""
        self._timed = self._timed and answer.t is not None
        lines = self._lines
        line = self._by_i.get(reply_to) if reply_to is not None else None
        if line is None:
            line = lines[-1] if lines else None
        if line is None:
            self._lead.append(answer)
            return
        line.answers.append(answer)
        at = answer.t
        if at is not None:
            k = len(lines) - 1  # the last line that began at or before the answer (they come in time order)
            while k >= 0 and not _began_by(lines[k], at):
                k -= 1
            if k >= 0 or self._before is not None:  # before every line held: the first held one
                lines[max(k, 0)].replies.append(answer)

    @property
    def lead(self) -> tuple[Answer, ...]:
        """Device bytes before any line."""
        return tuple(self._lead)

    def settled(self) -> list[CapturedLine]:
        """The lines final now (see the class docstring): every line but the last one seen, in order;
        each is handed out once."""
        return self._hand_out(len(self._lines) - 1)

    def finish(self) -> list[CapturedLine]:
        """The end of the capture: every line not handed out yet."""
        return self._hand_out(len(self._lines))

    def build(self) -> Script:
        """The whole script (the lines not handed out by ``settled``: all of them when it was not used)."""
        return Script(tuple(self.finish()), self.lead)

    def _hand_out(self, count: int) -> list[CapturedLine]:
        out: list[CapturedLine] = []
        lines = self._lines
        for line in lines[:max(count, 0)]:
            previous = self._before
            heard = self._replies(previous) if previous is not None else []
            after, gap = _pace(previous, heard, line)
            timed = tuple((a, _delay(line, a)) for a in self._replies(line))
            out.append(CapturedLine(self._n, line.i, line.raw, line.t, line.t_last, tuple(line.answers),
                                    timed, after, gap))
            self._n += 1
            self._before = line
            del self._by_i[line.i]
        del lines[:len(out)]
        return out

    def _replies(self, line: _Open) -> list[Answer]:
        """The device runs after ``line`` and before the next, by time; by the engine's pairing when the
        capture has no time."""
        return line.replies if self._timed else line.answers


def _began_by(line: _Open, t: float) -> bool:
    return line.t is not None and line.t <= t


def _delay(line: _Open, answer: Answer) -> float | None:
    if answer.t is None or line.t_last is None:
        return None
    return max(0.0, answer.t - line.t_last)


def _pace(previous: _Open | None, heard: list[Answer], line: _Open) -> tuple[bool, float | None]:
    """Was ``line`` sent after the device had answered ``previous`` (``heard``: the device bytes between
    the two), and the gap from the end of those bytes (or from the previous line's first byte when
    nothing came between: back to back, an overlap, a silence)."""
    if previous is None:
        return False, None
    if heard:
        last = heard[-1]
        end = last.t_last if last.t_last is not None else last.t
        return True, None if end is None or line.t is None else max(0.0, line.t - end)
    if previous.t is None or line.t is None:
        return False, None
    return False, max(0.0, line.t - previous.t)


# ---- the comparison ----

@dataclass(frozen=True, slots=True)
class Comparison:
    """How the answers received now compare with the captured ones: ``differences`` empty when the same,
    else the differing field names (wire order) or the kinds of ``KINDS``."""

    differences: tuple[str, ...] = ()

    @property
    def same(self) -> bool:
        return not self.differences


def compare(expected: Sequence[Answer], got: Sequence[Answer]) -> Comparison:
    """Compare the answers to one host line, pair by pair in order; more or fewer answers than captured
    are ``EXTRA`` or ``MISSING``."""
    found: list[str] = []
    for e, g in zip(expected, got, strict=False):
        for d in _one(e, g):
            if d not in found:
                found.append(d)
    if len(got) > len(expected):
        found.append(EXTRA)
    elif len(got) < len(expected):
        found.append(MISSING)
    return Comparison(tuple(found))


def _one(e: Answer, g: Answer) -> tuple[str, ...]:
    if e.raw == g.raw:
        return ()
    if e.alarm != g.alarm and (e.frame is not None or g.frame is not None):
        return (ALARM_INSTEAD,) if g.alarm else (ANSWER_INSTEAD,)
    if e.frame is None or g.frame is None:
        return (BYTES,)
    if e.header != g.header or type(e.frame) is not type(g.frame):
        return (HEADER,)
    fe, fg = e.frame.fields(), g.frame.fields()
    names = tuple(name for name in fe if fe[name] != fg.get(name))
    return names or (BYTES,)


# ---- the device side ----

@dataclass(frozen=True, slots=True)
class Match:
    """A received line found in the script: the captured lines it covers (several when line noise came
    as its own junk run before a frame), their answers with their delays, and how many captured lines
    were passed over to reach it."""

    lines: tuple[CapturedLine, ...]
    skipped: int

    @property
    def answers(self) -> tuple[tuple[Answer, float | None], ...]:
        return tuple(pair for line in self.lines for pair in line.replies)


class ScriptCursor:
    """Where the device side's replay stands: ``position`` is the next captured line not yet matched."""

    def __init__(self, script: Script) -> None:
        self.script = script
        self.position = 0
        self.matched = 0
        self.unmatched = 0

    def match(self, received: bytes) -> Match | None:
        """The next captured line (or run of lines ending in LF) equal to ``received``, from
        ``position`` on; the cursor moves past it. None (counted in ``unmatched``): not in the rest of
        the script; the cursor stays."""
        lines = self.script.lines
        for start in range(self.position, len(lines)):
            joined = b""
            for end in range(start, len(lines)):
                joined += lines[end].raw
                if len(joined) > len(received) or not received.startswith(joined):
                    break
                if joined == received:
                    skipped = start - self.position
                    self.position = end + 1
                    self.matched += 1
                    return Match(lines[start:end + 1], skipped)
        self.unmatched += 1
        return None

    @property
    def done(self) -> bool:
        return self.position >= len(self.script.lines)

    def where(self) -> str:
        """One line for the control channel and the log."""
        total = len(self.script.lines)
        if self.done:
            state = "at the end of the capture"
        else:
            nxt = self.script.lines[self.position]
            state = f"next captured line {self.position + 1} (record {nxt.i}): {_show(nxt.raw)}"
        return (f"replay: {self.position} of {total} captured host lines passed, {state}; "
                f"{self.matched} matched, {self.unmatched} not in the capture")


def _show(raw: bytes) -> str:
    return show_bytes(raw)


__all__ = ["ALARM_INSTEAD", "ANSWER_INSTEAD", "BYTES", "EXTRA", "HEADER", "KINDS", "MISSING", "SAME",
           "Answer", "CapturedLine", "Comparison", "Match", "Script", "ScriptBuilder", "ScriptCursor",
           "compare"]
