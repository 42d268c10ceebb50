"""Output sinks for analyzer records: a colour text view (rich) and JSON lines, plus the summary.

``make_view("text"|"jsonl", stream)`` gives an object with ``write(record)`` (``write_many(records)``:
the same for each) and ``summary(dict)``.
The text view prints one line per record (time, record number, direction, the raw bytes with escapes,
the decoded frame, and for answers which command they answer and the latency), then one line per
violation with its docs/protocol.md meaning and the detail; errors in red, notices in yellow. Colour is on
when the stream is a terminal (``color`` forces it). ``xac1 sniff``, ``xac1 proxy`` and ``xac1 decode``
share these.

One formatter a view, a loop over a batch of records: the text view's ``TextView.lines`` (each line its
pieces of text and their styles; without colour a line is their plain text), the JSON lines'
``JsonLines.lines`` (``sniffer.json_lines``); ``write(record)`` is ``write_many`` of one. Speed: a frame
record's line is its numbers around a part made once per distinct frame (``sniffer.frame_parts``), the
clock of the last whole second is remembered (``clock_second``), and offline lines are written in batches
(``_Lines``).
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Iterable, Iterator
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

# a line for people: its pieces of text, and the rich style of each ("" for none)
Line = tuple[tuple[str, ...], tuple[str, ...]]
# a frame record's text between its number and its tail (its bytes shown, its decode) and its line's styles
_Middle = tuple[str, str, tuple[str, ...]]

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
        """``write`` each record (offline: the lines of a batch taken from ``JsonLines.lines`` at once)."""
        if self.live or not self._lines.batched:
            for record in records:
                self.write(record)
            return
        lines = self._lines
        pending = lines.pending
        made = self._json.lines(records)
        while True:  # up to ``BATCH_LINES`` lines pending, then written (a line a record)
            before = len(pending)
            pending += islice(made, BATCH_LINES - before)
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
    """Lines for people; see the module docstring. A line is its pieces of text and the style of each
    (``Line``), never markup: bytes such as ``[bold]`` or ``:smile:`` are shown as they came."""

    def __init__(self, stream: IO[str], color: bool | None = None, live: bool = True) -> None:
        self.console = Console(file=stream, force_terminal=color, no_color=color is False,
                               highlight=False, soft_wrap=True, emoji=False)
        self.stream = stream
        # no colour system (a file, a pipe, --no-color): a line is the plain text of its pieces
        self._plain = self.console.color_system is None
        self._lines = _Lines(stream, live)
        self._second = math.nan  # the whole second of the last clock shown (``clock_second``)
        self._prefix = ""  # its clock, "HH:MM:SS."
        self._middles: FrameParts[_Middle] = FrameParts(_frame_middle)

    def write(self, record: Record) -> None:
        """The record's lines (``write_many`` of one)."""
        self.write_many((record,))

    def write_many(self, records: Iterable[Record]) -> None:
        """The lines of the records (``lines``), each printed as ``console.print`` prints its pieces:
        without colour that is their text joined (a line holding a tab, which the console expands, is left
        to it)."""
        plain, lines = self._plain, self._lines
        pending = lines.pending
        for texts, styles in self.lines(records):
            if plain:
                text = "".join(texts)
                if "\t" not in text:
                    if lines.batched:  # lines.add(text + "\n")
                        pending.append(text + "\n")
                        if len(pending) >= BATCH_LINES:
                            lines.write_pending()
                    else:
                        lines.add(text + "\n")
                    continue
            self._lines.write_pending()  # in order with what the console prints
            self.console.print(Text.assemble(*zip(texts, styles, strict=True)))

    def lines(self, records: Iterable[Record]) -> Iterator[Line]:
        """Each record's line, then a line per violation and line error (``_after``). A record's line is
        its time and number, then what it is: for a frame its direction, bytes and decode (made once per
        distinct frame, ``sniffer.frame_parts``) and on an answer the command it answers and the
        latency (``latency_shown``); junk (``_junk_line``); a missed answer (``_timeout_line``). The clock
        of the last whole second shown is remembered (``clock_second``)."""
        middle = self._middles.get
        second, prefix = self._second, self._prefix
        try:
            for record in records:
                if type(record) is FrameRecord:
                    (i, t, direction, raw, header, frame, violations, _details, reply_to, latency_s, _t_last,
                     line_errors, _sides, _window, _severities) = record
                else:
                    t = record.t
                if (type(t) is float and 0.0 <= (into := t - second) < 1.0
                        and (us := round(into * 1e6)) < 1_000_000):  # inside the last second shown
                    clock = prefix + _MS[us // 1000]
                else:
                    clock = show_time(t)
                    whole = clock_second(t, clock)
                    if whole is not None:
                        second, prefix = whole, clock[:-3]
                if type(record) is not FrameRecord:
                    yield _other_line(clock, record)  # type: ignore[arg-type]  # not a frame's
                    yield from _after(record)
                    continue
                shown, decoded, styles = middle(direction, raw, header, frame)
                if direction != "device" or reply_to is None:
                    tail = ""
                elif latency_s is None:
                    tail = f"  re #{reply_to}"
                elif (type(latency_s) is float and 0.0 <= (ms := latency_s * 1000.0) < 1e6
                      and not 0.494 <= ms * 10.0 % 1.0 <= 0.506):  # the note on latencies below
                    tail = f"  re #{reply_to}  {ms:.1f} ms"
                else:  # ``latency_ms``, one decimal shown
                    tail = f"  re #{reply_to}  {round(latency_s * 1000.0, 3):.1f} ms"
                # a record number from 1000 up fills its column: ``{i:<4}`` (slower) pads nothing
                head = f"{clock} #{i} " if type(i) is int and i >= 1000 else f"{clock} #{i:<4} "
                yield (head, shown, decoded, tail), styles
                if violations or line_errors:
                    yield from _after(record)
        finally:
            self._second, self._prefix = second, prefix

    def summary(self, summary: dict[str, Any]) -> None:
        self._lines.write_pending()
        for line in summary_lines(summary):
            self.console.print(line, emoji=False)
        self.flush()

    def flush(self) -> None:
        self._lines.write_pending()
        self.stream.flush()


# ``TextView.lines`` shows a latency of ``ms`` milliseconds (from 0 up to 1e6) as ``f"{ms:.1f}"`` when no tie
# of the one-decimal rounding (``k.k5``) is within 0.0006 ms of it: rounding to 3 decimals first
# (``latency_ms``, ``round(ms, 3)``) moves it by 0.0005 ms at most, never across that tie, so both give the
# same digit. ``ms * 10.0 % 1.0`` is that fraction to within 1e-9 below 1e6 ms.


def _other_line(clock: str, record: JunkRecord | TimeoutRecord) -> Line:
    """The line of a record other than a frame's: a missed answer's or a junk run's."""
    if isinstance(record, TimeoutRecord):
        return _timeout_line(clock, record)
    return _junk_line(clock, record)


def _timeout_line(clock: str, record: TimeoutRecord) -> Line:
    """A missed answer's line: the deadline, the command and its header, the time waited."""
    waited = "" if record.waited_s is None else f" within {record.waited_s:.3f} s"
    return ((f"{clock}       ",
             f"device ✗ no answer to #{record.command} ({record.header or 'unknown'}){waited}"),
            ("", "bold red"))


def _shown(direction: Any, raw: bytes) -> str:
    """A record's direction, arrow and bytes as typed."""
    arrow = "→" if direction == "host" else "←"
    return f"{direction:<6} {arrow} {show_raw(raw):<22}"


def _colour(direction: Any) -> str:
    """The style of a direction's bytes."""
    return "cyan" if direction == "host" else "green"


def _junk_line(clock: str, record: JunkRecord) -> Line:
    """A junk record's line: time, number, direction, bytes, why they are junk."""
    head, shown, colour = f"{clock} #{record.i:<4} ", _shown(record.dir, record.raw), _colour(record.dir)
    if record.reason == CAPTURE_ENDED:
        cut = "" if record.reply_to is None else f", the answer to #{record.reply_to}"
        return ((head, shown, " ", f"cut: the capture ended inside this frame{cut} (no violation)"),
                ("", colour, "", "yellow"))
    return (head, shown, " ", f"junk ({record.reason})"), ("", colour, "", "red")


def _frame_middle(direction: Any, raw: bytes, header: str | None, frame: Any) -> _Middle:
    """A frame record's line between its number and its tail: direction and bytes, what they decode to,
    and the styles of the line's pieces (``TextView.line``)."""
    if frame is None:
        decoded = f"{header or 'unknown'} (not decodable)"
    else:
        decoded = str(frame)
        if header == spec.ALARM_HEADER:
            decoded += f" ({spec.alarm_meaning(frame.fields()['code'])})"
    return _shown(direction, raw), f" {decoded}", ("", _colour(direction), "", "dim")


def _after(record: Record) -> list[Line]:
    """The lines after a record's line: its violations, then its line errors."""
    out = violation_parts(record)
    for error in getattr(record, "line_errors", ()):
        out.append((("      ", f"! line error: {error}"), ("", "magenta")))
    return out


def violation_parts(record: Record) -> list[Line]:
    """One line per violation code of a record: whose fault, code, docs/protocol.md meaning, the detail
    (``host ✗ letter-o: ...``)."""
    out: list[Line] = []
    details = list(record.details)
    for code, side, severity in zip(record.violations, sides_of(record), severities_of(record), strict=True):
        meaning = spec.VIOLATIONS[code][1]
        colour = "yellow" if severity == spec.NOTICE else "red"
        suffix = f" ({code})"
        detail = "; ".join(d.removesuffix(suffix) for d in details if d.endswith(suffix))
        mark = "!" if severity == spec.NOTICE else "✗"
        texts = ("      ", f"{side:<6} {mark} {code}", f": {meaning}")
        if detail:
            out.append(((*texts, " ", f"— {detail}"), ("", colour, "", "", "dim")))
        else:
            out.append((texts, ("", colour, "")))
    return out


def violation_lines(record: Record) -> list[str]:
    """The violation lines of a record as plain text."""
    return ["".join(texts) for texts, _ in violation_parts(record)]


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
