"""A fuzz run as plain data: each case's outcome, each finding after shrinking, the run's summary.

How this works: the shell appends a ``CaseResult`` per case and a ``Reported`` per finding (the finding
as found, its shrunk lines, the capture saved); ``RunSummary.of`` sums them up. ``RunSummary`` is the one
object a caller keeps of a run (a history database, the report, JUnit): frozen, JSON-ready through
``as_dict`` (the ``{"type": "summary"}`` line of ``--format jsonl`` is that dict). Lines are kept as
bytes; ``wire`` escapes them as the other views do (``\\r``, ``\\n``, ``\\xNN``).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from ..dut.evidence import wire
from .judge import KINDS, Finding

__all__ = ["CaseResult", "Reported", "RunSummary", "outcome", "wire"]


@dataclass(frozen=True)
class CaseResult:
    """One case: its number, generator, the writes sent, the unit's answer bytes, the engine's codes on
    the device, and the kind of finding it gave (None: none)."""

    i: int
    kind: str
    lines: tuple[bytes, ...]
    answered: bytes
    codes: tuple[str, ...]
    finding: str | None

    def as_dict(self) -> dict[str, Any]:
        return {"type": "case", "i": self.i, "generator": self.kind, "input": [wire(x) for x in self.lines],
                "answer": wire(self.answered), "codes": list(self.codes), "finding": self.finding}


@dataclass(frozen=True)
class Reported:
    """A finding as reported: found at case ``case``, ``found`` (the lines of the cases that led to it),
    ``finding`` (after shrinking: its lines are the fewest found), ``shrunk`` (False: reported as found,
    ``why`` says why), ``tries`` (re-runs spent), ``capture`` (the file saved, or None)."""

    case: int
    found: tuple[bytes, ...]
    finding: Finding
    shrunk: bool
    tries: int = 0
    why: str = ""
    capture: str | None = None

    def as_dict(self) -> dict[str, Any]:
        f = self.finding
        return {"type": "finding", "kind": f.kind, "input": [wire(x) for x in f.lines], "detail": f.detail,
                "codes": list(f.codes), "case": self.case, "shrunk": self.shrunk,
                "found_lines": len(self.found), "tries": self.tries, "not_shrunk_because": self.why or None,
                "capture": self.capture}


@dataclass(frozen=True)
class RunSummary:
    """What a run did and found: the object to keep of it (see the module docstring)."""

    port: str
    seed: int
    cases: int
    findings: tuple[Reported, ...]
    seconds: float
    version: str | None
    motion: bool
    interrupted: str | None
    stopped: str | None  # why the run ended early (the unit stopped answering), None when it did not
    restore: tuple[str, ...]
    restored: bool | None  # True: verified; False: not fully; None: not done
    exit: int
    generators: dict[str, int] = field(default_factory=dict)

    @classmethod
    def of(cls, results: list[CaseResult], findings: list[Reported], **rest: Any) -> RunSummary:
        return cls(cases=len(results), findings=tuple(findings),
                   generators=dict(sorted(Counter(r.kind for r in results).items())), **rest)

    @property
    def by_kind(self) -> dict[str, int]:
        counts = Counter(r.finding.kind for r in self.findings)
        return {k: counts[k] for k in KINDS}

    def as_dict(self) -> dict[str, Any]:
        return {"type": "summary", "cases": self.cases, "findings": len(self.findings),
                "by_kind": self.by_kind, "port": self.port, "seed": self.seed,
                "seconds": round(self.seconds, 3), "version": self.version, "motion": self.motion,
                "generators": self.generators, "interrupted": self.interrupted, "stopped": self.stopped,
                "restored": self.restored, "restore": list(self.restore), "exit": self.exit}


def outcome(s: RunSummary) -> str:
    """What the run found and how it ended, in words (the summary line and the history say it)."""
    kinds = ", ".join(f"{k} {n}" for k, n in s.by_kind.items() if n)
    found = f"{len(s.findings)} finding(s) ({kinds})" if s.findings else \
        "no finding: the unit stood up to every case"
    ended = f"; stopped by {s.interrupted}" if s.interrupted else ""
    early = f"; ended early: {s.stopped}" if s.stopped else ""
    return found + ended + early
