"""One fuzz run against a unit: cases, the liveness probe and state check after them, findings shrunk.

The shell around the sans-IO core (``xac1_proto.fuzz``): ``FuzzRun.run(stop)`` draws cases from the
seeded stream, sends each (``fuzz_unit.Unit``), probes liveness after each and reads the state back
every ``state_every`` cases and at the end. A finding is shrunk by re-running candidates against a fresh
unit (``shrink``; the simulator is started anew for each, a real unit is settled, or power-cycled by its
operator for a silence), confirmed once more with the late answer awaited, and its transcript kept as
the capture. After a finding the simulator starts afresh; a real unit that fell silent ends the run
unless its operator power-cycles it.
"""

from __future__ import annotations

import dataclasses
import random
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from xac1_proto.chunk import Chunk
from xac1_proto.dut.device import DeviceAbort, MotionRefused
from xac1_proto.dut.safety import Snapshot
from xac1_proto.fuzz.cases import ALL_POINTS, Case, Context, next_case
from xac1_proto.fuzz.judge import (
    ANSWER,
    SILENCE,
    STATE,
    Expectation,
    Finding,
    Transcript,
    answers_in,
    state_finding,
)
from xac1_proto.fuzz.results import CaseResult, Reported
from xac1_proto.fuzz.shrink import shrink

from .fuzz_unit import Unit, Unreadable, latched_after


@dataclass
class Limits:
    """When a run ends and how hard it shrinks."""

    cases: int | None
    seconds: float | None
    state_every: int = 20
    max_findings: int = 5
    shrink_budget: int = 150


@dataclass
class Trial:
    """One re-run of some lines against a fresh unit: the kind of finding it gave, what was seen, the
    engine's codes and the chunks of the re-run (the capture)."""

    kind: str | None
    detail: str = ""
    codes: tuple[str, ...] = ()
    chunks: list[Chunk] = field(default_factory=list)


class NoFreshStart(Exception):
    """The unit cannot be started afresh for a re-run (a real unit, nobody to power-cycle it)."""


class FuzzRun:
    """See the module docstring. ``on_case``/``on_finding`` see each result as it comes."""

    def __init__(self, unit: Unit, snap: Snapshot, version: bytes, seed: int, limits: Limits, *,
                 motion: bool, on_case: Callable[[CaseResult], None],
                 on_finding: Callable[[Reported, list[Chunk]], str | None]) -> None:
        self.unit = unit
        self.version = version
        self.limits = limits
        self.rng = random.Random(seed)
        writable = ALL_POINTS if unit.settings.simulator else \
            frozenset(n for n, p in snap.points.items() if p.restorable)
        self.ctx = Context(writable, unit.settings.safe_range if motion else None)
        self.expect = Expectation({n: (p.v, p.a, p.o, p.pos) for n, p in snap.points.items()}, snap.outputs)
        self.results: list[CaseResult] = []
        self.findings: list[Reported] = []
        self.stopped: str | None = None
        self.refused: list[str] = []  # move cases the motion guard refused (nothing sent)
        self.on_case = on_case
        self.on_finding = on_finding
        self._pending: list[bytes] = []  # writes since the last clean state check
        self._stop: Callable[[], bool] = lambda: False

    @property
    def transcript(self) -> Transcript:
        return self.unit.transcript

    def done(self, started: float) -> bool:
        lim = self.limits
        if lim.cases is not None and len(self.results) >= lim.cases:
            return True
        if lim.seconds is not None and time.monotonic() - started >= lim.seconds:
            return True
        return len(self.findings) >= lim.max_findings or self.stopped is not None

    def run(self, stop: Callable[[], bool]) -> None:
        """Cases until the limits say so or ``stop()``; then, unless stopped, the final state check."""
        self._stop = stop
        started = time.monotonic()
        while not stop() and not self.done(started):
            self.one(next_case(self.rng, self.ctx))
        if self._pending and not stop() and self.stopped is None:
            mark = self.transcript.mark()
            kind, detail = self._state_check()
            if kind is not None:
                finding = Finding(kind, tuple(self._pending), detail, self.transcript.device_codes(mark))
                self._report(len(self.results) - 1, finding, self.transcript.since(mark))

    # ---- one case ----

    def one(self, case: Case) -> None:
        """Send one case, probe liveness, check the state when due, report what was found."""
        i = len(self.results)
        mark = self.transcript.mark()
        try:
            answered = self.unit.send_move(case) if case.motion else self.unit.send_case(case)
        except MotionRefused as exc:  # nothing sent: the move is left out, the run goes on
            self.refused.append(f"case {i}: {exc}")
            answered = b""
        self._pending += case.lines
        self.expect.observe(answers_in(answered))
        live = self.unit.liveness(self.version, latched_after(answered, case))
        kind, detail = live if live else (None, "")
        if kind is None and (i + 1) % self.limits.state_every == 0:
            kind, detail = self._state_check()
        codes = self.transcript.device_codes(mark)
        result = CaseResult(i, case.kind, case.lines, answered, codes, kind)
        self.results.append(result)
        self.on_case(result)
        if kind is not None:
            lines = tuple(self._pending) if kind == STATE else case.lines
            self._report(i, Finding(kind, lines, detail, codes), self.transcript.since(mark))

    def _state_check(self) -> tuple[str | None, str]:
        try:
            points, outputs = self.unit.read_state()
        except Unreadable as exc:
            return ANSWER, f"the state read-back failed: {exc}"
        detail = state_finding(self.expect, points, outputs)
        if detail is None:
            self._pending = []
            return None, ""
        self.expect.accept(points, outputs)
        return STATE, detail

    # ---- a finding ----

    def _report(self, i: int, found: Finding, chunks: list[Chunk]) -> None:
        reported, capture_chunks = self._shrunk(i, found, chunks)
        capture = self.on_finding(reported, capture_chunks)
        self.findings.append(dataclasses.replace(reported, capture=capture))
        self._pending = []
        self._afresh(found.kind)

    def _shrunk(self, i: int, found: Finding, chunks: list[Chunk]) -> tuple[Reported, list[Chunk]]:
        if self.limits.shrink_budget <= 0:
            off = "shrinking was turned off (--shrink-budget 0)"
            return Reported(i, found.lines, found, False, why=off), chunks
        still = self._still(found.kind)
        try:
            result = shrink(found.lines, lambda lines: still(lines).kind == found.kind, self.ctx,
                            budget=self.limits.shrink_budget, stop=self._stop)
            confirmed = still(result.lines, wait_late=True)
        except NoFreshStart as exc:
            return Reported(i, found.lines, found, False, why=str(exc)), chunks
        if confirmed.kind != found.kind:
            return Reported(i, found.lines, found, False, tries=result.tries,
                            why="the shrunk lines did not produce it again: reported as found"), chunks
        f = Finding(found.kind, result.lines, confirmed.detail, confirmed.codes or found.codes)
        return Reported(i, found.lines, f, True, tries=result.tries), confirmed.chunks

    def _still(self, kind: str) -> Callable[..., Trial]:
        """A re-run of some lines against a fresh unit (see ``Trial``)."""
        unit = self.unit

        def trial(lines: tuple[bytes, ...], *, wait_late: bool = False) -> Trial:
            if (unit.settings.simulator or kind == SILENCE) and not unit.power_cycle():
                raise NoFreshStart("a silence on a real unit needs a power cycle for each re-run, and "
                                   "there is no terminal to ask for one: reported as found")
            mark = self.transcript.mark()
            try:
                unit.settle()
            except DeviceAbort:
                return Trial(None)
            version = self.version  # as it answered at the start: a fault that stays is still a fault
            expect = None
            if kind == STATE:
                try:
                    points, outputs = unit.read_state()
                except Unreadable:
                    return Trial(None)
                expect = Expectation(dict(points), outputs)
            case = Case("shrink", lines)
            answered = unit.send_case(case)
            live = unit.liveness(version, latched_after(answered, case), wait_late=wait_late)
            got, detail = live if live else (None, "")
            if got is None and expect is not None:
                expect.observe(answers_in(answered))
                try:
                    points, outputs = unit.read_state()
                except Unreadable as exc:
                    got, detail = ANSWER, str(exc)
                else:
                    d = state_finding(expect, points, outputs)
                    got, detail = (STATE, d) if d else (None, "")
            return Trial(got, detail, self.transcript.device_codes(mark), self.transcript.since(mark))

        return trial

    def _afresh(self, kind: str) -> None:
        """After a finding: the simulator starts anew; a real unit that fell silent is power-cycled by
        its operator, or the run ends."""
        unit = self.unit
        if (unit.settings.simulator or kind == SILENCE) and not unit.power_cycle():
            self.stopped = ("the unit stopped answering and there is no terminal to ask for a power "
                            "cycle: the run ends here")
            return
        try:
            unit.settle()
            points, outputs = unit.read_state()
        except (DeviceAbort, Unreadable) as exc:
            self.stopped = f"the unit did not come back after the finding: {exc}"
            return
        self.version = unit.version() or self.version
        self.expect = Expectation(dict(points), outputs)
