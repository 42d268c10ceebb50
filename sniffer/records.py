"""What the analyzer reports: one record per frame, per junk run and per missed answer, then a summary.

The records serialise to the pinned JSON lines schema (docs/output.md): ``FrameRecord`` ->
``{"type":"frame",...}``, ``JunkRecord`` -> ``{"type":"junk",...}``, ``TimeoutRecord`` ->
``{"type":"timeout",...}`` (the one violation that no frame carries: ``no-answer``), and the ``Tally``
that counts them gives the last line, ``{"type":"summary",...}``. Every record's ``sides`` lists, aligned
with ``violations``, whose fault each is (``host`` or ``device``: ``spec.VIOLATION_TABLE[code].side``);
the summary counts violations by side too (``by_side``). Records are inert data; the analyzer
builds them and the views print them.
"""

from __future__ import annotations

import json
import operator
from collections import Counter, defaultdict
from collections.abc import Iterable
from typing import Any, NamedTuple, Protocol

from xac1_proto import Frame, spec
from xac1_proto.chunk import Direction
from xac1_proto.conversation import side_of


def field_names(cls: type[Frame]) -> tuple[str, ...]:
    """A frame class's field names in ``Frame.fields``' order."""
    return cls.field_names()


def frame_fields(frame: Frame) -> dict[str, Any]:
    """``frame.fields()``."""
    return frame.fields()


def _round_t(t: float | None) -> float | None:
    return None if t is None else round(t, 6)


def _ms(seconds: float | None) -> float | None:
    return None if seconds is None else round(seconds * 1000.0, 3)


def _with_notes(out: dict[str, Any], details: tuple[str, ...],
                line_errors: tuple[str, ...]) -> dict[str, Any]:
    """Add the optional keys of frame and junk records: ``details`` and ``line_errors``."""
    if details:
        out["details"] = list(details)
    if line_errors:
        out["line_errors"] = list(line_errors)
    return out


class FrameRecord(NamedTuple):
    """A frame seen on one line. ``i``: position among frame and junk records; ``t``: time of its first
    byte; ``header``: the spec header it was read as (a letter O read as the digit), None when unknown;
    ``frame``: the lenient decode (None when a field could not be read); ``violations``: codes, each once;
    ``details``: one human sentence per violation; ``reply_to``/``latency_ms``: on device frames, the
    command answered and the time from its last byte to this frame's first byte; ``window_s``: on host
    frames, the answer window the rulebook gave it (not in JSON)."""

    i: int
    t: float | None
    dir: Direction
    raw: bytes
    header: str | None
    frame: Frame | None
    violations: tuple[spec.ViolationCode, ...] = ()
    details: tuple[str, ...] = ()
    reply_to: int | None = None
    latency_s: float | None = None
    t_last: float | None = None
    line_errors: tuple[str, ...] = ()
    sides: tuple[spec.Side, ...] = ()
    window_s: float | None = None
    severities: tuple[spec.Severity, ...] = ()

    @property
    def type(self) -> str:
        return "frame"

    @property
    def fields(self) -> dict[str, Any] | None:
        """``frame.fields()``: the field values by name in wire order."""
        frame = self.frame
        return None if frame is None else frame_fields(frame)

    @property
    def latency_ms(self) -> float | None:
        return _ms(self.latency_s)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "frame", "i": self.i, "t": _round_t(self.t), "dir": self.dir,
                               "raw": self.raw.hex(), "header": self.header, "fields": self.fields,
                               "violations": list(self.violations), "sides": _sides(self),
                               "severities": list(severities_of(self))}
        if self.dir == "device":
            out["reply_to"] = self.reply_to
            out["latency_ms"] = self.latency_ms
        return _with_notes(out, self.details, self.line_errors)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


CAPTURE_ENDED = "capture-ended"  # JunkRecord.reason: the data ended inside this frame (no violation)


class JunkRecord(NamedTuple):
    """Bytes that form no frame (the ``garbage`` violation). ``reason`` is the framer's:
    ``no-frame-start``, ``truncated``, ``overflow``, ``flushed``; or ``capture-ended``: the data (a capture
    file, a proxy stopped) ended inside this frame, which is no one's fault: no violation, and on device
    bytes ``reply_to`` names the command whose answer was cut."""

    i: int
    t: float | None
    dir: Direction
    raw: bytes
    reason: str
    violations: tuple[spec.ViolationCode, ...] = ("garbage",)
    details: tuple[str, ...] = ()
    line_errors: tuple[str, ...] = ()
    sides: tuple[spec.Side, ...] = ()
    reply_to: int | None = None  # device junk inside a command's answer window: its garbled answer
    latency_s: float | None = None
    severities: tuple[spec.Severity, ...] = ()

    @property
    def type(self) -> str:
        return "junk"

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "junk", "i": self.i, "t": _round_t(self.t), "dir": self.dir,
                               "raw": self.raw.hex(), "violations": list(self.violations),
                               "sides": _sides(self), "severities": list(severities_of(self)),
                               "reason": self.reason}
        if self.reply_to is not None:
            out["reply_to"] = self.reply_to
            out["latency_ms"] = _ms(self.latency_s)
        return _with_notes(out, self.details, self.line_errors)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


class TimeoutRecord(NamedTuple):
    """A command that got no answer in time (``no-answer``), reported when its deadline passed.
    ``command``: the command's ``i``; ``t``: the deadline (None when the source has no time and the
    verdict came at the end of the data); ``waited_s``: the timeout applied (None without time)."""

    command: int
    t: float | None
    header: str | None
    waited_s: float | None
    details: tuple[str, ...] = ()
    violations: tuple[spec.ViolationCode, ...] = ("no-answer",)
    dir: Direction = "host"
    sides: tuple[spec.Side, ...] = ()
    severities: tuple[spec.Severity, ...] = ()

    @property
    def type(self) -> str:
        return "timeout"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "timeout", "t": _round_t(self.t), "dir": self.dir, "command": self.command,
                "header": self.header, "waited_ms": _ms(self.waited_s),
                "violations": list(self.violations), "sides": _sides(self),
                "severities": list(severities_of(self)), "details": list(self.details)}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


Record = FrameRecord | JunkRecord | TimeoutRecord


_MAX_LATENCY_S = 1e6  # a latency beyond this comes from damaged times and is not counted
_US_PER_S = 1e6


def sides_of(record: Record) -> tuple[spec.Side, ...]:
    """Whose fault each violation of ``record`` is, aligned with ``record.violations``."""
    if len(record.sides) == len(record.violations):
        return record.sides
    sender: spec.Side = "device" if record.dir == "device" else "host"
    return tuple(spec.VIOLATION_TABLE[c].side(sender) for c in record.violations)


def severities_of(record: Record) -> tuple[spec.Severity, ...]:
    """The severity of each violation of ``record`` (``error`` or ``notice``: the engine's, which follows
    the rule's basis and the ``--readings`` setting), aligned with ``record.violations``; a record made
    without them has each code's plain severity."""
    if len(record.severities) == len(record.violations):
        return record.severities
    return tuple(spec.VIOLATIONS[c][0] for c in record.violations)


def _sides(record: Record) -> list[str]:
    return list(sides_of(record))


_MAX_WAITING = 4096  # commands the tally remembers while they wait for an answer


class LatencyStats:
    """Count, min, median and max of latencies in bounded memory: a histogram of whole microseconds (the
    summary shows 1 us, so the median is exact), whose size grows with distinct values, not answers.
    Latencies wait in a short list and go into the histogram ``FOLD`` at a time (in one C-level pass)."""

    __slots__ = ("n", "_us", "_waiting")

    FOLD = 4096

    def __init__(self) -> None:
        self.n = 0
        self._us: Counter[int] = Counter()
        self._waiting: list[float] = []

    def add(self, seconds: float) -> None:
        self.extend((seconds,))

    def extend(self, seconds: Iterable[float]) -> None:
        """Add latencies; a damaged time (NaN, infinite, absurd) is not one and is left out."""
        waiting = self._waiting
        before = len(waiting)
        waiting += [s for s in seconds if -_MAX_LATENCY_S <= s <= _MAX_LATENCY_S]
        self.n += len(waiting) - before
        if len(waiting) >= self.FOLD:
            self._fold()

    def _fold(self) -> None:
        """The waiting latencies into the histogram: ``round(seconds * 1e6)`` each."""
        self._us.update(map(round, map(_US_PER_S.__mul__, self._waiting)))
        self._waiting.clear()

    def _nth(self, k: int, keys: list[int]) -> int:
        """The k-th smallest value (0-based), in microseconds."""
        seen = 0
        for key in keys:
            seen += self._us[key]
            if seen > k:
                return key
        raise IndexError(k)

    def stats_ms(self) -> dict[str, float | int]:
        self._fold()
        keys = sorted(self._us)
        mid = (self._nth((self.n - 1) // 2, keys) + self._nth(self.n // 2, keys)) / 2
        return {"n": self.n, "min": keys[0] / 1000, "median": round(mid / 1000, 3), "max": keys[-1] / 1000}


_code = operator.attrgetter("code")  # a violation's code


class Counted(Protocol):
    """What ``Tally.count`` reads of a frame, junk run, frame the data ended inside or missed answer: the
    engine's ``Verdict`` has it all; ``Tally.add`` reads a record as one (``_RecordCounted``)."""

    @property
    def kind(self) -> str: ...  # a ``Verdict.kind``
    @property
    def sender(self) -> str: ...
    @property
    def raw(self) -> bytes: ...
    @property
    def header(self) -> str | None: ...
    @property
    def i(self) -> int | None: ...
    @property
    def reply_to(self) -> int | None: ...
    @property
    def latency_s(self) -> float | None: ...
    @property
    def violations(self) -> tuple[Any, ...]: ...  # each with its ``code``; empty when clean


class _RecordCounted(NamedTuple):
    """A record as ``Tally.count`` reads it."""

    kind: str
    sender: str
    raw: bytes
    header: str | None
    i: int | None
    reply_to: int | None
    latency_s: float | None
    violations: tuple[Any, ...]  # (none: ``add`` counts a record's violations by its own sides)


class Tally:
    """Counts what goes by (the analyzer's verdicts through ``count``, records through ``add``);
    ``summary()`` is the schema's last line."""

    def __init__(self) -> None:
        self.junk_runs = 0
        self.bytes: Counter[str] = Counter()  # by direction, frames and junk
        self.codes: Counter[str] = Counter()
        self.by_side: dict[str, Counter[str]] = {"host": Counter(), "device": Counter()}
        self.commands: dict[str, int] = {}  # host frames by header ("?" unknown)
        self.answers: dict[str, int] = {}  # device frames by header
        self.latencies: dict[str, LatencyStats] = {}  # by command header
        self.line_errors = 0  # frame and junk records carrying a line error
        self.unanswered = 0  # commands still waiting at the end with no verdict (capture cut short)
        self._headers: dict[int, str] = {}  # host frame i -> header, while it waits for its answer

    def add(self, record: Record) -> None:
        """Count one record."""
        codes = tuple(record.violations)
        if codes:
            self._count_violations(codes, sides_of(record))
        if isinstance(record, TimeoutRecord):
            self.count([_RecordCounted("no-answer", record.dir, b"", record.header, None, record.command,
                                       None, ())])
            return
        if isinstance(record, FrameRecord):
            kind, header = f"{record.dir}-frame", record.header
        else:
            kind, header = ("cut" if record.reason == CAPTURE_ENDED else f"{record.dir}-junk"), None
        self.count([_RecordCounted(kind, record.dir, record.raw, header, record.i, record.reply_to,
                                   record.latency_s, ())], bool(record.line_errors))

    def count(self, seen: Iterable[Counted], line_errors: int = 0) -> None:
        """Count frames, junk runs, frames the data ended inside and missed answers (``Counted``), of which
        ``line_errors`` carry a line error on their bytes: commands by header, answers by header with their
        latency by the command's header, violations by code and side. (One pass with locals, over plain
        dicts and lists, whose operations are the interpreter's fast ones, a ``Counter``'s += is not; the
        violations are counted a batch at a time by who sent them and the codes found, few distinct
        pairs however many verdicts: a misbehaving host repeats its violations; the latencies go to their
        ``LatencyStats`` a batch at a time.)"""
        commands, answers, headers = self.commands, self.answers, self._headers
        latencies: defaultdict[str, list[float]] = defaultdict(list)
        host_bytes = device_bytes = junk = 0
        found: dict[str, dict[Any, int]] = {"host": {}, "device": {}}  # sender -> code (or codes) -> verdicts
        for v in seen:
            kind = v.kind
            violations = v.violations
            if violations:
                by_key = found[v.sender]
                key = violations[0].code if len(violations) == 1 else tuple(map(_code, violations))
                by_key[key] = by_key.get(key, 0) + 1
            if kind == "host-frame":
                host_bytes += len(v.raw)
                header = v.header or "?"
                commands[header] = commands.get(header, 0) + 1
                headers[v.i] = header  # type: ignore[index]
                if len(headers) > _MAX_WAITING:  # commands never answered: forget the oldest
                    del headers[next(iter(headers))]
            elif kind == "device-frame":
                device_bytes += len(v.raw)
                header = v.header or "?"
                answers[header] = answers.get(header, 0) + 1
                reply_to = v.reply_to
                if reply_to is not None:
                    command = headers.pop(reply_to, "?")
                    latency_s = v.latency_s
                    if latency_s is not None:
                        latencies[command].append(latency_s)
            elif kind != "no-answer":  # a junk run, or a frame the data ended inside (its bytes, no junk run)
                if v.sender == "host":
                    host_bytes += len(v.raw)
                else:
                    device_bytes += len(v.raw)
                junk += kind != "cut"
        self.bytes["host"] += host_bytes
        self.bytes["device"] += device_bytes
        self.junk_runs += junk
        self.line_errors += line_errors
        for command, seconds in latencies.items():
            stats = self.latencies.get(command)
            if stats is None:
                stats = self.latencies[command] = LatencyStats()
            stats.extend(seconds)
        for sender, by_key in found.items():
            for key, n in by_key.items():
                for code in (key,) if type(key) is str else dict.fromkeys(key):  # (a verdict's codes, once)
                    self.codes[code] += n
                    self.by_side[side_of(code, sender)][code] += n  # type: ignore[arg-type]

    def _count_violations(self, codes: tuple[str, ...], sides: tuple[str, ...]) -> None:
        self.codes.update(codes)
        for code, side in zip(codes, sides, strict=True):
            self.by_side[side][code] += 1

    @property
    def frames(self) -> dict[str, int]:
        """Frames by direction."""
        return {"host": sum(self.commands.values()), "device": sum(self.answers.values())}

    def latency_stats(self) -> dict[str, dict[str, float | int]]:
        """Per command header: count, min, median, max latency in ms."""
        return {header: self.latencies[header].stats_ms() for header in sorted(self.latencies)
                if self.latencies[header].n}

    def summary(self) -> dict[str, Any]:
        ordered = sorted(self.codes.items(), key=lambda kv: list(spec.VIOLATIONS).index(kv[0])
                         if kv[0] in spec.VIOLATIONS else len(spec.VIOLATIONS))
        return {"type": "summary",
                "frames": {"host": self.frames["host"], "device": self.frames["device"]},
                "junk": self.junk_runs,
                "violations": dict(ordered),
                "by_side": {side: {c: self.by_side[side][c] for c, _ in ordered if self.by_side[side][c]}
                            for side in ("host", "device")},
                "bytes": {"host": self.bytes["host"], "device": self.bytes["device"]},
                "commands": dict(sorted(self.commands.items())),
                "answers": dict(sorted(self.answers.items())),
                "latency_ms": self.latency_stats(),
                "line_errors": self.line_errors,
                "unanswered": self.unanswered}


def summary_json(summary: dict[str, Any]) -> str:
    return json.dumps(summary, separators=(",", ":"))
