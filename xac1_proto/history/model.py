"""One run as inert data: ``RunRecord`` and its ``CheckRecord``s, whatever command made it.

How this works: a command that judges a device (``xac1 conformance``, ``xac1 replay``, later ``xac1
fuzz``) builds one ``RunRecord`` when it ends (``kind`` names the command) and hands it to
``history.record``; the store and the spool both take exactly this, so a spooled run is the same run
once synced. Times are timezone-aware; the store keeps them in UTC. ``uid`` identifies a run across
stores, so syncing a spooled run twice never records it twice.
"""

from __future__ import annotations

import datetime as _dt
import uuid
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

KINDS = ("conformance", "replay", "fuzz")
FAILED_OUTCOMES = ("FAIL", "ERROR")  # the outcomes that make a check's rule a failed rule
CONFORMS = "CONFORMS"


def now() -> _dt.datetime:
    """The current time, timezone-aware (local zone)."""
    return _dt.datetime.now().astimezone()


def utc(when: _dt.datetime) -> _dt.datetime:
    """``when`` in UTC (a naive time, as SQLite gives back, is taken to be UTC already)."""
    if when.tzinfo is None:
        return when.replace(tzinfo=_dt.timezone.utc)
    return when.astimezone(_dt.timezone.utc)


@dataclass(frozen=True, kw_only=True)
class CheckRecord:
    """One check's outcome: its name, the rule it checks, PASS/FAIL/ERROR/SKIP/MANUAL/NOT RUN/
    INTERRUPTED, the violation codes its exchanges showed, and the message it ended with."""

    name: str
    outcome: str
    rule: str = ""
    topic: str = ""
    codes: tuple[str, ...] = ()
    message: str = ""
    info: bool = False  # an information record (what the device does where the text is silent)

    @property
    def failed(self) -> bool:
        return self.outcome in FAILED_OUTCOMES and not self.info


@dataclass(frozen=True, kw_only=True)
class RunRecord:
    """One run of one unit: who, where, what, when, the verdict and exit status, every check, the
    settings it ran with and the files it wrote."""

    kind: str
    started: _dt.datetime
    ended: _dt.datetime
    verdict: str
    exit_status: int
    verdict_line: str = ""
    station: str | None = None
    operator: str | None = None
    port: str | None = None
    unit: str | None = None  # the serial number or asset tag (--unit-id, the fleet file's label)
    firmware: str | None = None  # what 0RV answered
    interrupted: str | None = None  # the signal that ended the run
    kit_version: str = ""
    fleet: str | None = None  # the fleet run this unit was tested in
    command_line: str = ""
    readings: str | None = None  # the rulebook's readings setting (notice|error), where the command has it
    settings: Mapping[str, str] = field(default_factory=dict)
    files: tuple[tuple[str, str], ...] = ()  # (what, path): report, junit, ...
    checks: tuple[CheckRecord, ...] = ()
    uid: str = field(default_factory=lambda: uuid.uuid4().hex)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"run kind {self.kind!r}: expected one of {', '.join(KINDS)}")

    @property
    def failed_rules(self) -> list[str]:
        """The checks that failed, in run order (each named once)."""
        return list(dict.fromkeys(c.name for c in self.checks if c.failed))

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (the spool's file); ``from_json`` reads it back."""
        data = asdict(self)
        data["started"], data["ended"] = self.started.isoformat(), self.ended.isoformat()
        data["settings"] = dict(self.settings)
        return data

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RunRecord:
        fields = dict(data)
        fields["started"] = _dt.datetime.fromisoformat(fields["started"])
        fields["ended"] = _dt.datetime.fromisoformat(fields["ended"])
        fields["files"] = tuple(tuple(f) for f in fields.get("files", ()))
        fields["checks"] = tuple(CheckRecord(**{**c, "codes": tuple(c.get("codes", ()))})
                                 for c in fields.get("checks", ()))
        return cls(**fields)
