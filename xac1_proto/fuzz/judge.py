"""What counts as a finding: the liveness probe, the state check, and the engine's codes for both.

How this works: ``Transcript`` keeps every chunk the run put on the line and got back (``Chunk``: time,
direction, bytes), cuts each direction with its own ``Framer`` and hands the frames and junk, in order,
to one ``Conversation`` (the one rulebook): ``device_codes(since)`` are the violation codes the engine
laid on the device since a mark, the codes a finding is also named with. ``Expectation`` is the state
the unit should hold: the snapshot taken at the start, updated by what the cases themselves wrote (an
echo of 0WP, the answer of 0WC, the echo of 0WS: the unit was told to; a move's answer makes the OUT
ports unknown until read again, docs/protocol.md silent item 8). ``probe_finding`` judges a liveness
probe against the answer the unit gave at the start; ``state_finding`` judges a read-back against the
expectation. A finding is ``silence`` (no answer within the answer window), ``answer`` (a well-formed
probe answered otherwise than at the start) or ``state`` (stored points or OUT ports changed untold).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Final

from .. import spec
from ..chunk import DEVICE, HOST, Chunk
from ..codec import diagnose, show_bytes
from ..conversation import Conversation, Verdict
from ..framer import Framer, Junk
from ..frames import (
    Frame,
    MoveDirectAnswer,
    MovePointAnswer,
    StoreCurrentAnswer,
    WriteOutputsAnswer,
    WritePointAnswer,
)

SILENCE: Final = "silence"
ANSWER: Final = "answer"
STATE: Final = "state"
KINDS: Final = (SILENCE, ANSWER, STATE)

Point = tuple[int, int, int, int]  # V, A, O, Pos as 0RP reads them


@dataclass(frozen=True)
class Finding:
    """A fault found: its ``kind``, the lines that produce it (``lines``: the writes, in order), what was
    seen (``detail``), the engine's violation codes laid on the device (``codes``)."""

    kind: str
    lines: tuple[bytes, ...]
    detail: str
    codes: tuple[str, ...] = ()


class Transcript:
    """Every chunk of a run, in order, judged as one conversation (see the module docstring)."""

    def __init__(self, no_answer_timeout: float = spec.NO_ANSWER_TIMEOUT_S) -> None:
        self.chunks: list[Chunk] = []
        self.verdicts: list[Verdict] = []
        self._timeout = no_answer_timeout
        self._conversation = Conversation(no_answer_timeout=no_answer_timeout)
        self._framers = {HOST: Framer(), DEVICE: Framer()}

    def add(self, direction: str, data: bytes, t: float) -> None:
        """Bytes one side put on the line at ``t`` (seconds, any clock that only goes forward)."""
        if not data:
            return
        self.chunks.append(Chunk(t, HOST if direction == HOST else DEVICE, bytes(data)))
        c = self._conversation
        out = c.tick(t)
        for event in self._framers[direction].feed(data, t):
            if direction == HOST:
                judge = c.host_junk if isinstance(event, Junk) else c.host_frame
                out += judge(event.raw, event.t_first, event.t_last, self._timeout)
            elif isinstance(event, Junk):
                out += c.device_junk(event.raw, event.t_first, event.t_last)
            else:
                out += c.device_frame(event.raw, event.t_first, event.t_last)
        self.verdicts += out

    def tick(self, now: float) -> None:
        """Time has passed with nothing on the line: a silence becomes ``no-answer``."""
        self.verdicts += self._conversation.tick(now)

    def mark(self) -> tuple[int, int]:
        """Where the transcript is now (chunks, verdicts), for ``since`` and ``device_codes``."""
        return len(self.chunks), len(self.verdicts)

    def since(self, mark: tuple[int, int]) -> list[Chunk]:
        return self.chunks[mark[0]:]

    def device_codes(self, mark: tuple[int, int]) -> tuple[str, ...]:
        """The violation codes laid on the device since ``mark``, each once, in the order found."""
        codes = [code for v in self.verdicts[mark[1]:] for code, side in zip(v.codes, v.sides, strict=True)
                 if side == spec.DEVICE_SIDE and code not in spec.NOTICES]
        return tuple(dict.fromkeys(codes))


def answers_in(data: bytes) -> list[Frame]:
    """The answer frames a lenient reading finds in ``data`` (bytes the unit sent)."""
    framer = Framer()
    out = []
    for event in framer.feed(data) + framer.flush():
        if isinstance(event, Junk):
            continue
        frame, _ = diagnose(event.raw, spec.ANSWER)
        if frame is not None:
            out.append(frame)
    return out


@dataclass
class Expectation:
    """The stored points and OUT ports the unit should hold (None: not known, taken as read next)."""

    points: dict[int, Point]
    outputs: int | None
    told: list[str] = field(default_factory=list)  # what the cases wrote, for the finding's detail

    def observe(self, answers: Iterable[Frame]) -> None:
        """What the unit said it did (its answers to the case's lines) becomes what it should hold."""
        for f in answers:
            if isinstance(f, (WritePointAnswer, StoreCurrentAnswer)) and f.n in self.points:
                self.points[f.n] = (f.v, f.a, f.o, f.pos)
                self.told.append(f"point {f.n:X} written ({f.header})")
            elif isinstance(f, WriteOutputsAnswer):
                self.outputs = f.o
                self.told.append("OUT ports written (0WS)")
            elif isinstance(f, (MovePointAnswer, MoveDirectAnswer)):
                self.outputs = None  # silent item 8: a point move may set the OUT ports

    def differences(self, points: Mapping[int, Point], outputs: int) -> list[str]:
        """How a read-back differs from the expectation, one sentence an item."""
        out = [f"point {n:X} reads {_point(points[n])}, expected {_point(want)}"
               for n, want in sorted(self.points.items()) if n in points and points[n] != want]
        if self.outputs is not None and outputs != self.outputs:
            out.append(f"OUT ports read {outputs}, expected {self.outputs}")
        return out

    def accept(self, points: Mapping[int, Point], outputs: int) -> None:
        """Take a read-back as the new expectation (after a finding, so one fault is reported once)."""
        self.points.update(points)
        self.outputs = outputs


def _point(p: Point) -> str:
    v, a, o, pos = p
    return f"V={v} A={a} O={o} Pos={pos:06X}"


def probe_finding(expected: bytes | None, got: bytes, probe: bytes, *, late_s: float | None,
                  window_s: float) -> tuple[str, str] | None:
    """(kind, detail) when the liveness probe ``probe`` was not answered within ``window_s``, or answered
    otherwise than ``expected`` (None: any answer will do, as for the alarm reset before 0RV);
    ``late_s``: when bytes came after the window, how long after the probe was sent."""
    what = show_bytes(probe)
    if not got:
        late = "" if late_s is None else f"; bytes came only {late_s:.2f} s after it was sent (late)"
        return SILENCE, f"{what} got no answer within {window_s:.2f} s{late}"
    if expected is not None and got != expected:
        return ANSWER, f"{what} answered {show_bytes(got)}; at the start it answered {show_bytes(expected)}"
    return None


def state_finding(expect: Expectation, points: Mapping[int, Point], outputs: int) -> str | None:
    """A sentence saying what changed untold, or None."""
    diffs = expect.differences(points, outputs)
    if not diffs:
        return None
    told = f" (the cases wrote: {', '.join(dict.fromkeys(expect.told))})" if expect.told else \
        " (no case wrote anything the unit acknowledged)"
    return "; ".join(diffs) + told
