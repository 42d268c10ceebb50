"""Output sinks for analyzer records: a colour text view (rich) and JSON lines, plus the summary.

``make_view("text"|"jsonl", stream)`` gives an object with ``write(record)`` (``write_many(records)``:
the same for each) and ``summary(dict)``.
The text view prints one line per record (time, record number, direction, the raw bytes with escapes,
the decoded frame, and for answers which command they answer and the latency), then one line per
violation with its docs/protocol.md meaning and the detail; errors in red, notices in yellow. Colour is on
when the stream is a terminal (``color`` forces it). ``xac1 sniff``, ``xac1 proxy`` and ``xac1 decode``
share these.

One formatter a view: the text view's ``line`` (styled pieces; without colour a line is their plain
text), the JSON lines' ``sniffer.json_lines`` (``record.to_json()`` is its line). Speed: a frame record's
line is its numbers around a part made once per distinct frame (``sniffer.frame_parts``), the clock of the
last whole second is remembered (``clock_second``), and offline lines are written in batches (``_Lines``).
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Iterable
from itertools import islice
from typing import IO, Any, Protocol

from rich.console import Console
from rich.markup import escape
from rich.text import Text

from xac1_proto import spec

from .frame_parts import FrameParts
from .json_lines import JsonLines
from .records import (
    CAPTURE_ENDED,
    FrameRecord,
    JunkRecord,
    Record,
    TimeoutRecord,
    severities_of,
    sides_of,
    summary_json,
)

FORMATS = ("text", "jsonl")
_ESCAPES = {0x0D: "\\r", 0x0A: "\\n", 0x5C: "\\\\"}
# byte -> how it is shown: printable ASCII as is, CR LF and backslash escaped, the rest \xNN
_SHOWN = {b: _ESCAPES.get(b) or (chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02X}") for b in range(256)}
BATCH_LINES = 512  # an offline view writes this many lines at a time (one write, not one per line)

Part = tuple[str, str]  # a piece of a line and its rich style ("" for none)

_MS = tuple(f"{ms:03d}" for ms in range(1000))


class View(Protocol):
    def write(self, record: Record) -> None: ...
    def write_many(self, records: Iterable[Record]) -> None: ...
    def summary(self, summary: dict[str, Any]) -> None: ...
    def flush(self) -> None: ...


def show_raw(raw: bytes) -> str:
    """Bytes as typed: printable ASCII as is, ``\\r`` ``\\n``, others ``\\xNN``."""
    return raw.decode("latin-1").translate(_SHOWN)


def show_time(t: float | None) -> str:
    if t is None:
        return "-" * 12
    try:
        d = _dt.datetime.fromtimestamp(t)
    except (ValueError, OverflowError, OSError):  # NaN, infinite or absurd: a damaged time
        return f"{'?' + repr(t):>12.12}"
    return f"{d.hour:02d}:{d.minute:02d}:{d.second:02d}.{d.microsecond // 1000:03d}"


def clock_second(t: Any, shown: str) -> float | None:
    """The whole second whose clock ``shown`` (``show_time(t)``) shows, for a time from 0 that
    ``datetime.fromtimestamp`` does not round up into the next second; else None (no time, not a float,
    damaged, negative). ``datetime`` splits a float time with C ``modf`` and rounds the microseconds half
    to even; for a time ``t`` inside that second, ``t - second`` is exactly the fraction ``modf`` gives,
    so ``round((t - second) * 1e6)`` is the microsecond it rounds to (``TextView._clock`` shows the
    clock of the times inside the last second so). The local time zone is read once a second: a
    ``time.tzset`` inside a second shows from the next."""
    if type(t) is not float or "?" in shown or not t >= 0.0:
        return None
    second = float(int(t))
    return second if round((t - second) * 1e6) < 1_000_000 else None


class _Lines:
    """Where a view's lines go: straight to the stream (``live``, or a terminal), or gathered and written
    ``BATCH_LINES`` at a time (an offline decode into a file or a pipe: one write per batch instead of
    one per line, which is what a stream without a buffer, PYTHONUNBUFFERED=1, would otherwise cost)."""

    def __init__(self, stream: IO[str], live: bool) -> None:
        self.stream = stream
        self.batched = not live and not _is_terminal(stream)
        self.pending: list[str] = []  # lines gathered, not yet written

    def add(self, line: str) -> None:
        if not self.batched:
            self.stream.write(line)
            return
        self.pending.append(line)
        if len(self.pending) >= BATCH_LINES:
            self.write_pending()

    def write_pending(self) -> None:
        if self.pending:
            self.stream.write("".join(self.pending))
            self.pending.clear()


def _is_terminal(stream: IO[str]) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


class JsonlView:
    """One JSON object a line (the docs/output.md schema), flushed as it goes when ``live`` (the sniffer);
    an offline decode (``live=False``) writes lines in batches and flushes after the summary. A line is
    exactly ``record.to_json()`` (``sniffer.json_lines``)."""

    def __init__(self, stream: IO[str], live: bool = True) -> None:
        self.stream = stream
        self.live = live
        self._lines = _Lines(stream, live)
        self._json = JsonLines()

    def write(self, record: Record) -> None:
        self._lines.add(self._json.line(record))
        if self.live:
            self.stream.flush()

    def write_many(self, records: Iterable[Record]) -> None:
        """``write`` each record (offline: the lines of a batch made in one loop)."""
        if self.live or not self._lines.batched:
            for record in records:
                self.write(record)
            return
        lines, extend = self._lines, self._json.extend
        pending = lines.pending
        remaining = iter(records)
        while True:  # up to ``BATCH_LINES`` lines pending, then written (a line a record)
            wanted = BATCH_LINES - len(pending)
            extend(islice(remaining, wanted), pending)
            if len(pending) < BATCH_LINES:
                return
            lines.write_pending()

    def line(self, record: Record) -> str:
        """``record.to_json()`` and a newline."""
        return self._json.line(record)

    def summary(self, summary: dict[str, Any]) -> None:
        self._lines.add(summary_json(summary) + "\n")
        self.flush()

    def flush(self) -> None:
        self._lines.write_pending()
        self.stream.flush()


class TextView:
    """A line per record for people; see the module docstring. A line is built as styled pieces
    (``Part``), never as markup: bytes such as ``[bold]`` or ``:smile:`` are shown as they came."""

    def __init__(self, stream: IO[str], color: bool | None = None, live: bool = True) -> None:
        self.console = Console(file=stream, force_terminal=color, no_color=color is False,
                               highlight=False, soft_wrap=True, emoji=False)
        self.stream = stream
        # no colour system (a file, a pipe, --no-color): a line is the plain text of its pieces
        self._plain = self.console.color_system is None
        self._lines = _Lines(stream, live)
        self._second = math.nan  # the whole second of the last clock shown (``clock_second``)
        self._prefix = ""  # its clock, "HH:MM:SS."
        self._middles: FrameParts[tuple[Part, Part]] = FrameParts(_frame_middle)

    def _print(self, parts: list[Part]) -> None:
        """One line: what ``console.print`` prints of the pieces."""
        if self._plain:
            plain = "".join([text for text, _ in parts])
            if "\t" not in plain:  # tabs the console expands: left to it
                self._lines.add(plain + "\n")
                return
        self._lines.write_pending()  # in order with what the console prints
        self.console.print(Text.assemble(*parts))

    def write(self, record: Record) -> None:
        """The record's line (``line``), then its violations and line errors."""
        self._print(self.line(record))
        if record.violations or getattr(record, "line_errors", ()):
            for parts in _after(record):
                self._print(parts)

    def write_many(self, records: Iterable[Record]) -> None:
        """``write`` each record."""
        for record in records:
            self.write(record)

    def line(self, record: Record) -> list[Part]:
        """The record's line as styled pieces: time, record number, then what the record is (for a frame
        its direction, bytes and decode, made once per distinct frame: ``sniffer.frame_parts``), and on
        an answer the command it answers and the latency."""
        if isinstance(record, FrameRecord):
            (i, t, direction, raw, header, frame, _violations, _details, reply_to, latency_s, _t_last,
             _line_errors, _sides, _window, _severities) = record
            shown, decoded = self._middles.get(direction, raw, header, frame)
            if direction != "device" or reply_to is None:
                tail = ""
            elif latency_s is None:
                tail = f"  re #{reply_to}"
            else:  # the latency as ``latency_ms`` has it, one decimal shown
                tail = f"  re #{reply_to}  {round(latency_s * 1000.0, 3):.1f} ms"
            return [(f"{self._clock(t)} #{i:<4} ", ""), shown, decoded, (tail, "dim")]
        if isinstance(record, TimeoutRecord):
            when = show_time(record.t)
            waited = "" if record.waited_s is None else f" within {record.waited_s:.3f} s"
            return [(f"{when}       ", ""),
                    (f"device ✗ no answer to #{record.command} ({record.header or 'unknown'}){waited}",
                     "bold red")]
        return [(f"{self._clock(record.t)} #{record.i:<4} ", ""), *_junk_body(record)]

    def _clock(self, t: Any) -> str:
        """``show_time(t)``, the clock of the last whole second shown remembered (``clock_second``)."""
        if (type(t) is float and 0.0 <= (into := t - self._second) < 1.0
                and (us := round(into * 1e6)) < 1_000_000):  # inside the last second shown
            return self._prefix + _MS[us // 1000]
        clock = show_time(t)
        whole = clock_second(t, clock)
        if whole is not None:
            self._second, self._prefix = whole, clock[:-3]
        return clock

    def summary(self, summary: dict[str, Any]) -> None:
        self._lines.write_pending()
        for line in summary_lines(summary):
            self.console.print(line, emoji=False)
        self.flush()

    def flush(self) -> None:
        self._lines.write_pending()
        self.stream.flush()


def _shown(direction: Any, raw: bytes) -> Part:
    """A record's direction, arrow and bytes as typed, in its direction's colour."""
    arrow = "→" if direction == "host" else "←"
    colour = "cyan" if direction == "host" else "green"
    return (f"{direction:<6} {arrow} {show_raw(raw):<22}", colour)


def _junk_body(record: JunkRecord) -> list[Part]:
    """A junk record's line but its time and number: direction, bytes, why they are junk."""
    shown = _shown(record.dir, record.raw)
    if record.reason == CAPTURE_ENDED:
        cut = "" if record.reply_to is None else f", the answer to #{record.reply_to}"
        return [shown, (" ", ""), (f"cut: the capture ended inside this frame{cut} (no violation)", "yellow")]
    return [shown, (" ", ""), (f"junk ({record.reason})", "red")]


def _frame_middle(direction: Any, raw: bytes, header: str | None, frame: Any) -> tuple[Part, Part]:
    """A frame record's line between its number and its tail: direction and bytes, what they decode to."""
    if frame is None:
        decoded = f"{header or 'unknown'} (not decodable)"
    else:
        decoded = str(frame)
        if header == spec.ALARM_HEADER:
            decoded += f" ({spec.alarm_meaning(frame.fields()['code'])})"
    return _shown(direction, raw), (f" {decoded}", "")


def _after(record: Record) -> list[list[Part]]:
    """The lines after a record's line: its violations, then its line errors."""
    out = violation_parts(record)
    for error in getattr(record, "line_errors", ()):
        out.append([("      ", ""), (f"! line error: {error}", "magenta")])
    return out


def violation_parts(record: Record) -> list[list[Part]]:
    """One line per violation code of a record: whose fault, code, docs/protocol.md meaning, the detail
    (``host ✗ letter-o: ...``), as styled pieces."""
    out = []
    details = list(record.details)
    for code, side, severity in zip(record.violations, sides_of(record), severities_of(record), strict=True):
        meaning = spec.VIOLATIONS[code][1]
        colour = "yellow" if severity == spec.NOTICE else "red"
        suffix = f" ({code})"
        detail = "; ".join(d.removesuffix(suffix) for d in details if d.endswith(suffix))
        mark = "!" if severity == spec.NOTICE else "✗"
        parts: list[Part] = [("      ", ""), (f"{side:<6} {mark} {code}", colour), (f": {meaning}", "")]
        if detail:
            parts += [(" ", ""), (f"— {detail}", "dim")]
        out.append(parts)
    return out


def violation_lines(record: Record) -> list[str]:
    """The violation lines of a record as plain text."""
    return ["".join(text for text, _ in parts) for parts in violation_parts(record)]


def summary_lines(summary: dict[str, Any]) -> list[str]:
    """The summary for people: frames, frames per command with latency, violations with meanings."""
    frames = summary.get("frames", {})
    head = (f"[bold]summary[/]: {frames.get('host', 0)} host frames, {frames.get('device', 0)} device "
            f"frames, {summary.get('junk', 0)} junk runs")
    if summary.get("line_errors"):
        head += f", {summary['line_errors']} records with line errors"
    if summary.get("unanswered"):
        head += f", {summary['unanswered']} commands still waiting at the end"
    lines = [head]
    commands = summary.get("commands", {})
    latency = summary.get("latency_ms", {})
    if commands:
        lines.append("  command  frames  latency ms min / median / max")
        for header, count in commands.items():
            stats = latency.get(header)
            shown = "-"
            if stats:
                plural = "answer" if stats["n"] == 1 else "answers"
                spread = f"{stats['min']:.1f} / {stats['median']:.1f} / {stats['max']:.1f}"
                shown = f"{spread} ({stats['n']} {plural})"
            lines.append(f"  {escape(header):<7}  {count:>6}  {shown}")
    violations = summary.get("violations", {})
    by_side = summary.get("by_side", {})
    if not violations:
        lines.append("  [green]no violations[/]")
    for code, count in violations.items():
        severity, meaning = spec.VIOLATIONS[code]
        colour = "yellow" if severity == spec.NOTICE else "red"
        sides = ", ".join(f"{side} {by_side[side][code]}" for side in ("host", "device")
                          if by_side.get(side, {}).get(code))
        lines.append(f"  [{colour}]{code}[/] x{count}{f' ({sides})' if sides else ''}: {escape(meaning)}")
    return lines


def make_view(fmt: str, stream: IO[str], color: bool | None = None, live: bool = True) -> View:
    """The sink for ``--format``: ``text`` or ``jsonl`` (``live``: every record written and flushed as
    it comes; else lines are written in batches until ``flush()``)."""
    if fmt == "jsonl":
        return JsonlView(stream, live)
    if fmt == "text":
        return TextView(stream, color, live)
    raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")


__all__ = ["FORMATS", "FrameRecord", "JsonlView", "TextView", "View", "make_view", "show_raw", "show_time",
           "summary_lines", "violation_lines", "violation_parts"]
