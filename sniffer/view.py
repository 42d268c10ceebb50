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
# byte -> how it is shown: printable ASCII as is, CR LF and backslash escaped, the rest \xNN
_SHOWN = {b: _ESCAPES.get(b) or (chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02X}") for b in range(256)}
BATCH_LINES = 512  # an offline view writes this many lines at a time (one write, not one per line)

Part = tuple[str, str]  # a piece of a line and its rich style ("" for none)


class View(Protocol):
    def write(self, record: Record) -> None: ...
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


class _Lines:
    """Where a view's lines go: straight to the stream (``live``, or a terminal), or gathered and written
    ``BATCH_LINES`` at a time (an offline decode into a file or a pipe: one write per batch instead of
    one per line, which is what a stream without a buffer, PYTHONUNBUFFERED=1, would otherwise cost)."""

    def __init__(self, stream: IO[str], live: bool) -> None:
        self.stream = stream
        self.batched = not live and not _is_terminal(stream)
        self._pending: list[str] = []

    def add(self, line: str) -> None:
        if not self.batched:
            self.stream.write(line)
            return
        self._pending.append(line)
        if len(self._pending) >= BATCH_LINES:
            self.write_pending()

    def write_pending(self) -> None:
        if self._pending:
            self.stream.write("".join(self._pending))
            self._pending.clear()


def _is_terminal(stream: IO[str]) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


class JsonlView:
    """One JSON object a line (the README's schema), flushed as it goes when ``live`` (the sniffer);
    an offline decode (``live=False``) writes lines in batches and flushes after the summary."""

    def __init__(self, stream: IO[str], live: bool = True) -> None:
        self.stream = stream
        self.live = live
        self._lines = _Lines(stream, live)

    def write(self, record: Record) -> None:
        self._lines.add(record.to_json() + "\n")
        if self.live:
            self.stream.flush()

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

    def _print(self, parts: list[Part]) -> None:
        """One line: what ``console.print`` prints of the pieces."""
        if self._plain:
            plain = "".join(text for text, _ in parts)
            if "\t" not in plain:  # tabs the console expands: left to it
                self._lines.add(plain + "\n")
                return
        self._lines.write_pending()  # in order with what the console prints
        self.console.print(Text.assemble(*parts))

    def write(self, record: Record) -> None:
        self._print(self.line(record))
        for parts in violation_parts(record):
            self._print(parts)
        for error in getattr(record, "line_errors", ()):
            self._print([("      ", ""), (f"! line error: {error}", "magenta")])

    def line(self, record: Record) -> list[Part]:
        when = show_time(record.t)
        if isinstance(record, TimeoutRecord):
            waited = "" if record.waited_s is None else f" within {record.waited_s:.3f} s"
            return [(f"{when}       ", ""),
                    (f"device ✗ no answer to #{record.command} ({record.header or 'unknown'}){waited}",
                     "bold red")]
        arrow = "→" if record.dir == "host" else "←"
        colour = "cyan" if record.dir == "host" else "green"
        head = [(f"{when} #{record.i:<4} ", ""),
                (f"{record.dir:<6} {arrow} {show_raw(record.raw):<22}", colour)]
        if isinstance(record, JunkRecord):
            return [*head, (" ", ""), (f"junk ({record.reason})", "red")]
        if record.frame is None:
            decoded = f"{record.header or 'unknown'} (not decodable)"
        else:
            decoded = str(record.frame)
            if record.header == spec.ALARM_HEADER:
                decoded += f" ({spec.alarm_meaning(record.frame.fields()['code'])})"
        tail = ""
        if record.dir == "device" and record.reply_to is not None:
            tail = f"  re #{record.reply_to}"
            if record.latency_ms is not None:
                tail += f"  {record.latency_ms:.1f} ms"
        return [*head, (f" {decoded}", ""), (tail, "dim")]

    def summary(self, summary: dict[str, Any]) -> None:
        self._lines.write_pending()
        for line in summary_lines(summary):
            self.console.print(line, emoji=False)
        self.flush()

    def flush(self) -> None:
        self._lines.write_pending()
        self.stream.flush()


def violation_parts(record: Record) -> list[list[Part]]:
    """One line per violation code of a record: whose fault, code, docs/protocol.md meaning, the detail
    (``host ✗ letter-o: ...``), as styled pieces."""
    out = []
    details = list(record.details)
    for code, side in zip(record.violations, sides_of(record), strict=True):
        severity, meaning = spec.VIOLATIONS[code]
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


__all__ = ["FORMATS", "FrameRecord", "JsonlView", "TextView", "View", "make_view", "show_raw",
           "summary_lines", "violation_lines", "violation_parts"]
