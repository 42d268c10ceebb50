"""Output sinks for analyzer records: a colour text view (rich) and JSON lines, plus the summary.

``make_view("text"|"jsonl", stream)`` gives an object with ``write(record)`` and ``summary(dict)``.
The text view prints one line per record (time, record number, direction, the raw bytes with escapes,
the decoded frame, and for answers which command they answer and the latency), then one line per
violation with its docs/protocol.md meaning and the detail; errors in red, notices in yellow. Colour is on
when the stream is a terminal (``color`` forces it). ``xac1 sniff``, ``xac1 proxy`` and ``xac1 decode``
share these.
"""

from __future__ import annotations

import datetime as _dt
from typing import IO, Any, Protocol

from rich.console import Console
from rich.markup import escape
from rich.text import Text

from xac1_proto import spec

from .records import FrameRecord, JunkRecord, Record, TimeoutRecord, sides_of, summary_json

FORMATS = ("text", "jsonl")
_ESCAPES = {0x0D: "\\r", 0x0A: "\\n", 0x5C: "\\\\"}


class View(Protocol):
    def write(self, record: Record) -> None: ...
    def summary(self, summary: dict[str, Any]) -> None: ...


def show_raw(raw: bytes) -> str:
    """Bytes as typed: printable ASCII as is, ``\\r`` ``\\n``, others ``\\xNN``."""
    return "".join(_ESCAPES.get(b) or (chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02X}") for b in raw)


def show_time(t: float | None) -> str:
    if t is None:
        return "-" * 12
    try:
        return _dt.datetime.fromtimestamp(t).strftime("%H:%M:%S.%f")[:-3]
    except (ValueError, OverflowError, OSError):  # NaN, infinite or absurd: a damaged time
        return f"{'?' + repr(t):>12.12}"


class JsonlView:
    """One JSON object a line (the README's schema), flushed as it goes when ``live`` (the sniffer);
    an offline decode (``live=False``) leaves buffering to the stream and flushes after the summary."""

    def __init__(self, stream: IO[str], live: bool = True) -> None:
        self.stream = stream
        self.live = live

    def write(self, record: Record) -> None:
        self.stream.write(record.to_json() + "\n")
        if self.live:
            self.stream.flush()

    def summary(self, summary: dict[str, Any]) -> None:
        self.stream.write(summary_json(summary) + "\n")
        self.stream.flush()


class TextView:
    """A line per record for people; see the module docstring."""

    def __init__(self, stream: IO[str], color: bool | None = None) -> None:
        self.console = Console(file=stream, force_terminal=color, no_color=color is False,
                               highlight=False, soft_wrap=True)
        self.stream = stream
        # no colour system (a file, a pipe, --no-color): a line is its markup's plain text, which rich
        # makes the same way without the console's per-print rendering
        self._plain = self.console.color_system is None

    def _print(self, markup: str) -> None:
        """One line: what ``console.print(markup)`` prints."""
        if self._plain:
            plain = Text.from_markup(markup).plain
            if "\t" not in plain:  # tabs the console expands: left to it
                self.stream.write(plain + "\n")
                return
        self.console.print(markup)

    def write(self, record: Record) -> None:
        self._print(self.line(record))
        for line in violation_lines(record):
            self._print(line)
        for error in getattr(record, "line_errors", ()):
            self._print(f"      [magenta]! line error: {escape(error)}[/]")

    def line(self, record: Record) -> str:
        when = show_time(record.t)
        if isinstance(record, TimeoutRecord):
            waited = "" if record.waited_s is None else f" within {record.waited_s:.3f} s"
            return (f"{when}       [bold red]device ✗ no answer to #{record.command} "
                    f"({record.header or 'unknown'}){waited}[/]")
        arrow = "→" if record.dir == "host" else "←"
        colour = "cyan" if record.dir == "host" else "green"
        raw = escape(show_raw(record.raw))
        head = f"{when} #{record.i:<4} [{colour}]{record.dir:<6} {arrow} {raw:<22}[/]"
        if isinstance(record, JunkRecord):
            return f"{head} [red]junk ({record.reason})[/]"
        decoded = "?" if record.frame is None else str(record.frame)
        if record.frame is not None and record.header == spec.ALARM_HEADER:
            decoded += f" ({spec.alarm_meaning(record.frame.fields()['code'])})"
        if record.frame is None:
            decoded = f"{record.header or 'unknown'} (not decodable)"
        tail = ""
        if record.dir == "device" and record.reply_to is not None:
            tail = f"  re #{record.reply_to}"
            if record.latency_ms is not None:
                tail += f"  {record.latency_ms:.1f} ms"
        return f"{head} {escape(decoded)}[dim]{tail}[/]"

    def summary(self, summary: dict[str, Any]) -> None:
        for line in summary_lines(summary):
            self.console.print(line)


def violation_lines(record: Record) -> list[str]:
    """One line per violation code of a record: whose fault, code, docs/protocol.md meaning, the detail
    (``host ✗ letter-o: ...``)."""
    out = []
    details = list(record.details)
    for code, side in zip(record.violations, sides_of(record), strict=True):
        severity, meaning = spec.VIOLATIONS[code]
        colour = "yellow" if severity == spec.NOTICE else "red"
        suffix = f" ({code})"
        mine = [d.removesuffix(suffix) for d in details if d.endswith(suffix)]
        detail = "; ".join(mine)
        mark = "!" if severity == spec.NOTICE else "✗"
        out.append(f"      [{colour}]{side:<6} {mark} {code}[/]: {escape(meaning)}"
                   + (f" [dim]— {escape(detail)}[/]" if detail else ""))
    return out


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
    """The sink for ``--format``: ``text`` or ``jsonl`` (``live``: flush every record)."""
    if fmt == "jsonl":
        return JsonlView(stream, live)
    if fmt == "text":
        return TextView(stream, color)
    raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")


__all__ = ["FORMATS", "FrameRecord", "JsonlView", "TextView", "View", "make_view", "show_raw",
           "summary_lines", "violation_lines"]
