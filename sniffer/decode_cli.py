"""``xac1 decode``: read a capture made by any common serial tool and show the checked conversation.

A thin shell: ``sniffer.io.registry`` picks the reader (content sniffing, or ``--input-format``) and
turns the files into chunks merged by time; the sniffer's ``Analyzer`` makes records; the sniffer's
views print them. Problems in the file (a malformed line, a truncated record) are listed on stderr
with file and line, and what could be read is decoded anyway.

Exit status: 0 every byte read and no violation; 1 violations found or part of the capture could not be
read (or the file looks cut short); 2 nothing decoded (missing file, unknown format, bad option, a
capture holding no line data).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .io.registry import Capture

HELP = "decode a capture file (socat, spy://, interceptty, jpnevulator, Saleae, sigrok, pcap, raw, jsonl)"
PROGRESS_MIN_BYTES = 1 << 20  # show a progress bar on a terminal from this file size up
_INPUT_FORMATS = ("auto", "jsonl", "pcap", "socat", "spy", "interceptty", "jpnevulator", "saleae",
                  "sigrok", "raw")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = ("host side by default: socat '>'; spy TX; interceptty '>'; jpnevulator the tty named host, "
                "else the first to speak; saleae the file/analyzer named host, else the first file; sigrok "
                "uart-1 (several decoder instances) or tx-data (one); pcap TX; raw the file named host, else "
                "the first file. See README \"Decoding captures\".")
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="capture file(s); formats with one file per direction take two")
    p.add_argument("--input-format", "-I", default="auto", choices=_INPUT_FORMATS,
                   help="the capture's format (default: sniffed from the content)")
    p.add_argument("--format", "-f", default="text", choices=("text", "jsonl", "summary"),
                   help="output: a line per frame (text), the JSON lines schema (jsonl), or only the summary")
    p.add_argument("--only-violations", action="store_true",
                   help="show only records with a violation (the summary still counts everything)")
    p.add_argument("--header", action="append", metavar="HDR", default=None,
                   help="show only frames of this command header (and their answers), e.g. 0MV; repeatable")
    p.add_argument("--host-is", metavar="SIDE", default=None,
                   help="which side is the host, named as the format names it: socat '>' or '<', spy TX/RX, "
                        "a jpnevulator alias or tty, a sigrok instance (uart-1) or class (tx-data), a Saleae "
                        "file or analyzer name, a raw file, pcap TX/RX")
    p.add_argument("--samplerate", type=float, metavar="HZ", default=None,
                   help="sigrok: sample rate turning sample numbers (--protocol-decoder-samplenum) into "
                        "time (default: inferred from the byte lengths at 9600 baud)")
    p.add_argument("--timeout", "--no-answer-timeout", dest="no_answer_timeout", type=float, metavar="S",
                   default=None, help="no-answer timeout in seconds after a command's last byte; moves get "
                                      "their estimated time doubled on top (default 1.0, as xac1 sniff)")
    p.add_argument("--storm-limit", type=int, default=None, metavar="N",
                   help="communication-error answers in a row after which a command is comm-error-storm "
                        "(default 5)")
    p.add_argument("--color", action=argparse.BooleanOptionalAction, default=None,
                   help="colour in the text view (default: when the output is a terminal)")
    p.add_argument("--annotate", metavar="OUT.pcapng", default=None,
                   help="also write the capture as pcapng for Wireshark, every verdict as a packet comment")


def _error(message: str) -> int:
    print(f"xac1 decode: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .io.base import FormatError
    from .io.registry import SURE, Capture, detect

    for f in args.files:
        path = Path(f)
        if not path.exists():
            return _error(f"{f}: no such file")
        if path.is_dir():
            return _error(f"{f}: is a directory; give the capture file(s) in it")
    try:
        fmt = args.input_format
        if fmt == "auto":
            found = detect(args.files)
            fmt = found.name
            close = [(n, s) for n, s in found.considered[1:] if s >= SURE]
            if close:
                others = ", ".join(f"{n} ({s})" for n, s in close)
                print(f"xac1 decode: reading as {fmt} (also considered: {others})", file=sys.stderr)
        if len(args.files) == 1 and fmt in ("saleae", "raw"):
            partner = _partner(args.files[0])
            if partner is not None:
                print(f"xac1 decode: {fmt} keeps one line direction a file: reading {partner} with it",
                      file=sys.stderr)
                args.files.append(partner)
        with Capture(args.files, fmt, host_is=args.host_is, samplerate=args.samplerate) as capture:
            return _decode(capture, args)
    except FormatError as exc:
        return _error(str(exc))
    except BrokenPipeError:  # output piped into head & co.
        sys.stderr.close()
        return 0
    except OSError as exc:
        return _error(f"{exc.filename or ''}: {exc.strerror or exc}")


def _decode(capture: Capture, args: argparse.Namespace) -> int:
    from .analyzer import Analyzer
    from .view import make_view

    options: dict[str, Any] = {}
    if args.no_answer_timeout is not None:
        options["no_answer_timeout"] = args.no_answer_timeout
    if args.storm_limit is not None:
        options["storm_limit"] = args.storm_limit
    analyzer = Analyzer(**options)
    annotate = _annotated(args, capture)
    color = args.color
    view = make_view("text" if args.format == "summary" else args.format, sys.stdout, color)
    show = _Filter(args.only_violations, args.header) if args.format != "summary" else None
    progress = _Progress(capture) if sys.stderr.isatty() and capture.size >= PROGRESS_MIN_BYTES else None
    violations = 0
    for chunk in capture:
        records = analyzer.feed(chunk)
        if annotate is not None:
            annotate.write(chunk, records)
        for record in records:
            violations += bool(record.violations)
            if show is not None and show(record):
                view.write(record)
        if progress is not None:
            progress.update()
    records = analyzer.close()
    if annotate is not None:
        annotate.verdicts(records)
        annotate.close()
    for record in records:
        violations += bool(record.violations)
        if show is not None and show(record):
            view.write(record)
    if progress is not None:
        progress.done()
    view.summary(analyzer.summary())
    report = capture.report
    empty = not (analyzer.bytes_in("host") or analyzer.bytes_in("device"))
    for note in report.notes:
        print(f"xac1 decode: note: {note}", file=sys.stderr)
    for problem in report.problems:
        print(f"xac1 decode: {problem}", file=sys.stderr)
    if report.dropped:
        print(f"xac1 decode: ... and {report.dropped} more problem(s)", file=sys.stderr)
    if empty:
        print(f"xac1 decode: {', '.join(args.files)}: no line data found in this {capture.format} "
              f"capture: nothing to decode", file=sys.stderr)
        return 2
    if report.total_problems or report.unread_bytes or report.unread_lines:
        print(f"xac1 decode: {capture.format}: {report.summary()}; the rest was decoded", file=sys.stderr)
    return 1 if violations or report.total_problems else 0


def _annotated(args: argparse.Namespace, capture: Capture) -> Any:
    """``--annotate``: the pcapng recorder (``sniffer.io.pcapng_writer``), or None."""
    if args.annotate is None:
        return None
    from pathlib import Path

    from .io.base import FormatError
    from .io.pcapng_writer import PcapngRecorder

    if any(Path(args.annotate).resolve() == Path(f).resolve() for f in args.files):
        raise FormatError(f"--annotate {args.annotate}: that is an input file; give another name")

    return PcapngRecorder(args.annotate, source=f"xac1 decode {' '.join(args.files)} ({capture.format})")


def _partner(path: str) -> str | None:
    """The other direction's file of a one-file-per-direction capture: ``host`` <-> ``device`` in the
    name (``saleae-host.csv`` -> ``saleae-device.csv``), when that file exists."""
    import os
    import re

    folder, name = os.path.split(path)
    swap = {"host": "device", "device": "host", "Host": "Device", "Device": "Host", "HOST": "DEVICE",
            "DEVICE": "HOST"}
    other, n = re.subn(r"host|device", lambda m: swap.get(m.group(0), m.group(0)), name, count=1,
                       flags=re.IGNORECASE)
    candidate = os.path.join(folder, other)
    return candidate if n and candidate != path and os.path.isfile(candidate) else None


class _Filter:
    """--only-violations and --header: which records to show (answers follow their command)."""

    def __init__(self, only_violations: bool, headers: list[str] | None) -> None:
        self.only_violations = only_violations
        self.headers = {h.strip() for h in headers} if headers else None
        self.shown_commands: set[int] = set()

    def __call__(self, record: Any) -> bool:
        if self.headers is not None:
            header = getattr(record, "header", None)
            related = getattr(record, "reply_to", None) in self.shown_commands or \
                getattr(record, "command", None) in self.shown_commands
            if header not in self.headers and not related:
                return False
            if record.type == "frame" and record.dir == "host":
                self.shown_commands.add(record.i)
        return not self.only_violations or bool(record.violations)


class _Progress:
    """A one-line progress bar on stderr, redrawn at most five times a second."""

    def __init__(self, capture: Capture) -> None:
        self.capture = capture
        self.last = 0.0

    def update(self) -> None:
        now = time.monotonic()
        if now - self.last < 0.2:
            return
        self.last = now
        size = max(1, self.capture.size)
        done = min(1.0, self.capture.pos / size)
        bar = "#" * int(done * 30)
        sys.stderr.write(f"\rdecoding [{bar:<30}] {done * 100:5.1f}% of {size / 1e6:.1f} MB")
        sys.stderr.flush()

    def done(self) -> None:
        sys.stderr.write("\r" + " " * 60 + "\r")
        sys.stderr.flush()
