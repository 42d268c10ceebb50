"""``xac1 decode``: read a capture made by any common serial tool and show the checked conversation.

A thin shell in three parts: argument parsing (``add_arguments``, each value checked as it is parsed),
source opening (``sniffer.capture_args``, shared with ``xac1 replay``: each file opened once, ``-`` being
standard input; the format sniffed from the buffered heads by ``sniffer.io.registry``), and output
(``_decode``, in named steps: ``_opening`` the first chunk, ``_analyzer`` with the rule options and the
lines the capture holds (a one-direction capture is told to the engine, which then judges only what one
line's bytes show), ``_Outputs`` where records go, ``_read_all`` the chunks through the analyzer (through
the HTML report when there is one, which asks the engine after each line), ``_summary``, ``_publish``,
``_exit_status``; the sniffer's ``Analyzer`` judges, its views print; with ``--format summary`` alone no
record is made). Problems in the
file (a malformed line, a damaged record) are listed on stderr with file and line or byte offset, counted
in the summary record, and what could be read is decoded anyway.

Exit status: 0 every byte read and no violation; 1 violations found or problems in the capture (their
count is said, and is ``problems`` in the JSON lines summary); 2 nothing decoded (missing file, unknown
or wrong format, bad option, a capture holding no line data).
"""

from __future__ import annotations

import argparse
import gc
import math
import sys
import time
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Final

from xac1_proto import rules, spec
from xac1_proto.speed_option import add_speed_table_option, speeds_of

from .capture_args import WRONG_FORMAT_LIMIT, add_capture_arguments, choose_format, open_sources

if TYPE_CHECKING:
    from collections.abc import Iterator

    from xac1_proto.chunk import Chunk
    from xac1_proto.conversation import Directions

    from .io.base import Report, Source
    from .io.registry import Capture

HELP = "decode a capture file (socat, spy://, interceptty, jpnevulator, Saleae, sigrok, pcap, raw, jsonl)"
PROGRESS_MIN_BYTES = 1 << 20  # show a progress bar on a terminal from this file size up
WRONG_FORMAT_SHOWN: Final = 3  # of which this many are printed
SUMMARY_PROBLEMS: Final = 5  # problem messages copied into the JSON lines summary record
_HEADERS: Final = frozenset(spec.HEADERS[spec.COMMAND] | spec.HEADERS[spec.ANSWER])
GC_YOUNG: Final = 10_000  # a decode's youngest-generation threshold (Python's default: 700)


def _seconds(text: str) -> float:
    """``--timeout``: a positive, finite number of seconds."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value) or value <= 0 or value > 86400:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number of seconds above 0 and at most 86400")
    return value


def _count(text: str) -> int:
    """``--storm-limit``: a whole number from 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give a whole number from 1")
    return value


def _header(text: str) -> str:
    """``--header``: a command or answer header of the protocol (``0MV``)."""
    header = text.strip().upper()
    if header not in _HEADERS:
        raise argparse.ArgumentTypeError(f"{text!r} is not a header of the protocol; one of: "
                                         f"{', '.join(sorted(_HEADERS))}")
    return header


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = ("host side by default: socat '>'; spy TX; interceptty '<'; jpnevulator the tty named host, "
                "else the first to speak; saleae the file/analyzer named host, else the first file; sigrok "
                "uart-1 (several decoder instances) or tx-data (one); pcap TX; raw the file named host, else "
                "the first file. See docs/captures.md.")
    add_capture_arguments(p)
    p.add_argument("--format", "-f", default="text", choices=("text", "jsonl", "summary"),
                   help="output: a line per frame (text), the JSON lines schema (jsonl), or only the summary")
    p.add_argument("--only-violations", action="store_true",
                   help="show only records with a violation (the summary still counts everything)")
    p.add_argument("--header", action="append", metavar="HDR", default=None, type=_header,
                   help="show only frames of this command header (and their answers), e.g. 0MV; repeatable")
    p.add_argument("--timeout", "--no-answer-timeout", dest="no_answer_timeout", type=_seconds, metavar="S",
                   default=None, help="no-answer timeout in seconds after a command's last byte; moves get "
                                      f"their estimated time doubled on top (default "
                                      f"{spec.NO_ANSWER_TIMEOUT_S:g}, as xac1 sniff)")
    p.add_argument("--storm-limit", type=_count, default=None, metavar="N",
                   help="communication-error answers in a row after which a command is comm-error-storm "
                        f"(default {spec.STORM_LIMIT})")
    p.add_argument("--readings", choices=rules.READINGS, default=rules.DEFAULT_READINGS,
                   help=rules.READINGS_HELP)
    add_speed_table_option(p)
    p.add_argument("--color", action=argparse.BooleanOptionalAction, default=None,
                   help="colour in the text view (default: when the output is a terminal)")
    p.add_argument("--report", metavar="FILE", default=None,
                   help="also write an HTML session report to FILE (needs the 'report' extra)")
    p.add_argument("--annotate", metavar="OUT.pcapng", default=None,
                   help="also write the capture as pcapng for Wireshark, every verdict as a packet comment")
    p.add_argument("--batch", action="store_true",
                   help="an archive: each FILE is a directory, a file or a glob pattern, every file one "
                        "conversation, decoded in its own process; prints a summary row per file and a total")
    p.add_argument("--jobs", "-j", type=_count, metavar="N", default=None,
                   help="--batch: files decoded at once (default: the cores)")



def _error(message: str) -> int:
    print(f"xac1 decode: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace, summaries: list[dict[str, Any]] | None = None) -> int:
    """Decode; ``summaries``: collect the summary record (with the format) instead of printing it."""
    from .io.base import FormatError, Report
    from .io.registry import Capture

    if getattr(args, "batch", False):
        from .decode_batch import run as run_batch
        return run_batch(args, run)

    report = Report()
    sources: list[Source] = []
    try:
        if args.report is not None and _all_empty(args.files):  # nothing to detect, but the report says so
            return _empty_report(args)
        sources = open_sources(args.files, report)
        fmt, one_sided = choose_format(sources, args, report, "xac1 decode")
        with Capture(sources, fmt, host_is=args.host_is, samplerate=args.samplerate,
                     report=report) as capture, _few_collections():
            return _decode(capture, args, one_sided, summaries)
    except FormatError as exc:
        return _error(str(exc))
    except BrokenPipeError:  # output piped into head & co.
        sys.stderr.close()
        return 0
    except OSError as exc:
        return _error(f"{exc.filename or ''}: {exc.strerror or exc}")
    finally:
        for src in sources:
            src.close()


# ---- source opening ----

def _all_empty(files: list[str]) -> bool:
    from pathlib import Path

    from .io.base import STDIN

    return all(f != STDIN and Path(f).is_file() and Path(f).stat().st_size == 0 for f in files)


def _empty_report(args: argparse.Namespace) -> int:
    """Zero-byte files: no format to detect, nothing to decode; the report says so."""
    from .report import ReportError, write_empty

    try:
        written = write_empty(args.report, [(f, "empty") for f in args.files])
    except ReportError as exc:
        return _error(str(exc))
    print(f"xac1 decode: report written to {written}", file=sys.stderr)
    return 2


def _annotated(args: argparse.Namespace, capture: Capture) -> Any:
    """``--annotate``: the pcapng recorder (``sniffer.io.pcapng_writer``), or None."""
    if args.annotate is None:
        return None
    from pathlib import Path

    from .io.base import FormatError
    from .io.pcapng_writer import PcapngRecorder

    if any(Path(args.annotate).resolve() == Path(f).resolve() for f in args.files):
        raise FormatError(f"--annotate {args.annotate}: that is an input file; give another name")

    try:
        return PcapngRecorder(args.annotate, source=f"xac1 decode {' '.join(args.files)} ({capture.format})")
    except OSError as exc:
        raise FormatError(f"--annotate {args.annotate}: {exc.strerror or exc}") from None


# ---- output ----

def _decode(capture: Capture, args: argparse.Namespace, one_sided: bool = False,
            summaries: list[dict[str, Any]] | None = None) -> int:
    """The analyzer over the whole capture, its records to the outputs, then the summary and the exit
    status (module docstring). A one-direction capture is told to the engine (the direction of its
    first chunk), which then judges only what one line's bytes show."""
    from .io.base import WrongFormat
    from .report import ReportError

    try:
        first, chunks = _opening(capture)
    except WrongFormat:
        return _wrong_format(capture)
    analyzer = _analyzer(args, first.dir if one_sided and first is not None else "both")
    try:
        outputs = _Outputs(capture, args, analyzer.conversation.no_answer_timeout)
    except ReportError as exc:
        return _error(str(exc))
    try:
        with _progress(capture) as progress:
            _read_all(chunks, analyzer, outputs, progress)
    finally:
        outputs.view.flush()  # the lines decoded so far are out, however the loop ended (Ctrl-C included)
    outputs.end(analyzer.close())
    summary = _summary(analyzer, capture.report)
    _publish(summary, capture, outputs, summaries)
    return _exit_status(summary, analyzer, capture)


def _analyzer(args: argparse.Namespace, directions: Directions) -> Any:
    """The analyzer with the rule options given (``--timeout``, ``--storm-limit``, ``--readings``,
    ``--speed-table``) and the lines the capture holds."""
    from .analyzer import Analyzer

    options: dict[str, Any] = {"readings": args.readings, "speeds": speeds_of(args), "directions": directions}
    if args.no_answer_timeout is not None:
        options["no_answer_timeout"] = args.no_answer_timeout
    if args.storm_limit is not None:
        options["storm_limit"] = args.storm_limit
    return Analyzer(**options)


class _Outputs:
    """Where a decode's records go: the view (through ``--only-violations`` and ``--header``), the HTML
    report and the annotated pcapng. ``wants_records``: False when only the summary is shown (the
    analyzer then counts its verdicts and makes no record)."""

    def __init__(self, capture: Capture, args: argparse.Namespace, timeout: float) -> None:
        from .view import make_view

        self.annotate = _annotated(args, capture)
        self.html_report = None
        if args.report is not None:
            from .report import SessionReport
            files = [(s.name, capture.format) for s in capture.sources]
            self.html_report = SessionReport.open(args.report, files, timeout)
        summary_only = args.format == "summary"
        self.view = make_view("text" if summary_only else args.format, sys.stdout, args.color, live=False)
        self.show = None if summary_only else _Filter(args.only_violations, args.header)
        # every record to the view, in one call a batch
        self.plain = not summary_only and not args.only_violations and not args.header
        self.wants_records = not summary_only or self.chunk_by_chunk

    @property
    def chunk_by_chunk(self) -> bool:
        """Do records go to an output a chunk at a time (the annotated pcapng, the HTML report)?"""
        return self.annotate is not None or self.html_report is not None

    def take(self, chunk: Chunk, analyzer: Any) -> None:
        """One chunk through the analyzer (through the HTML report when there is one, which asks the
        engine after each line), its records to the annotated pcapng with it and to the view."""
        if self.html_report is not None:
            records = self.html_report.feed(analyzer, chunk)
        else:
            records = analyzer.feed(chunk)
        if self.annotate is not None:
            self.annotate.write(chunk, records)
        self.emit(records)

    def emit(self, records: list[Any]) -> None:
        """Records to the view (in one call), through ``--only-violations`` and ``--header``."""
        if self.plain:
            self.view.write_many(records)
            return
        show = self.show
        if show is not None:
            self.view.write_many([record for record in records if show(record)])

    def end(self, records: list[Any]) -> None:
        """The records of the end of the data; the annotated pcapng is closed with them."""
        if self.annotate is not None:
            self.annotate.verdicts(records)
            self.annotate.close()
        if self.html_report is not None:
            for record in records:
                self.html_report.add(record)
        self.emit(records)
        self.view.flush()


def _read_all(chunks: Iterator[Chunk], analyzer: Any, outputs: _Outputs,
              progress: _Progress | _NoProgress) -> None:
    """Every chunk of the capture through the analyzer: one at a time when annotating or reporting (each
    chunk written with its records; the report asks the engine after each line), else in batches
    (``Analyzer.feed_many``)."""
    if outputs.chunk_by_chunk:
        for chunk in chunks:
            outputs.take(chunk, analyzer)
            progress.update()
        return
    if not outputs.wants_records:
        while analyzer.feed_many(chunks):
            progress.update()
        return
    pending: list[Any] = []
    try:
        while analyzer.feed_many(chunks, pending):
            outputs.emit(pending)
            pending = []
            progress.update()
    except BaseException:  # Ctrl-C too: the records of every chunk taken are shown
        outputs.emit(pending)
        raise


def _wrong_format(capture: Capture) -> int:
    """``--input-format`` named a format the file is not (problems and no data at the start)."""
    report = capture.report
    _print_problems(report, WRONG_FORMAT_SHOWN)
    looks = f" ({report.looks_like})" if report.looks_like else ""
    return _error(f"{WRONG_FORMAT_LIMIT} problems and no line data at the start: this is not a "
                  f"{capture.format} capture{looks}; leave --input-format out to detect the format")


def _summary(analyzer: Any, report: Report) -> dict[str, Any]:
    """The summary record, with the capture's problems and notes."""
    summary: dict[str, Any] = analyzer.summary()
    if report.total_problems:
        summary["problems"] = report.total_problems
        summary["problem_messages"] = report.problems[:SUMMARY_PROBLEMS]
    if report.notes:
        summary["notes"] = list(report.notes)
    return summary


def _publish(summary: dict[str, Any], capture: Capture, outputs: _Outputs,
             summaries: list[dict[str, Any]] | None) -> None:
    """The summary to the view (or to ``summaries``), the HTML report written, notes and problems said."""
    if summaries is None:
        outputs.view.summary(summary)
    else:
        summaries.append({"format": capture.format, **summary})
    if outputs.html_report is not None:
        print(f"xac1 decode: report written to {outputs.html_report.write(summary)}", file=sys.stderr)
    for note in capture.report.notes:
        print(f"xac1 decode: note: {note}", file=sys.stderr)
    _print_problems(capture.report)


def _exit_status(summary: dict[str, Any], analyzer: Any, capture: Capture) -> int:
    """2 when the capture held no line data, 1 with violations or problems, else 0."""
    report = capture.report
    if not (analyzer.bytes_in("host") or analyzer.bytes_in("device")):
        names = ", ".join(s.name for s in capture.sources)
        looks = f" ({report.looks_like})" if report.looks_like else ""
        print(f"xac1 decode: {names}: no line data found in this {capture.format} capture: nothing to "
              f"decode{looks}", file=sys.stderr)
        return 2
    if report.total_problems or report.unread_bytes or report.unread_lines:
        print(f"xac1 decode: {capture.format}: {report.summary()}; the rest was decoded", file=sys.stderr)
    return 1 if summary["violations"] or report.total_problems else 0


@contextmanager
def _few_collections() -> Iterator[None]:
    """A decode makes millions of short-lived objects that form no cycles (chunks, records, lines), so
    the cyclic garbage collector, run every 700 allocations by default, finds nothing but costs a
    jsonl decode about 7% (measured): during the decode it runs every ``GC_YOUNG``, and the objects that
    exist already (the grammar, the modules) are frozen out of its scans. Both are restored after."""
    threshold = gc.get_threshold()
    gc.freeze()
    gc.set_threshold(GC_YOUNG, *threshold[1:])
    try:
        yield
    finally:
        gc.set_threshold(*threshold)
        gc.unfreeze()


def _opening(capture: Capture) -> tuple[Chunk | None, Iterator[Chunk]]:
    """The capture's first chunk (None: it holds none) and all its chunks; from the first on, no longer a
    wrong format however many problems follow (the others come from the capture's own iterator, through
    ``chain``)."""
    import itertools

    chunks = iter(capture)
    for first in chunks:
        capture.report.give_up_after = None
        return first, itertools.chain((first,), chunks)
    return None, chunks


def _print_problems(report: Report, at_most: int | None = None) -> None:
    shown = report.problems[:at_most]
    for problem in shown:
        print(f"xac1 decode: {problem}", file=sys.stderr)
    if report.total_problems > len(shown):
        print(f"xac1 decode: ... and {report.total_problems - len(shown)} more problem(s)", file=sys.stderr)


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
    """A progress bar on stderr (``rich.progress``), fed at most five times a second, removed at the
    end."""

    def __init__(self, capture: Capture) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, DownloadColumn, Progress, TextColumn

        self.capture = capture
        self.last = 0.0
        self.bar = Progress(TextColumn("decoding"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                            DownloadColumn(), console=Console(stderr=True), transient=True,
                            refresh_per_second=5)
        self.task = self.bar.add_task("decoding", total=max(1, capture.size))

    def __enter__(self) -> _Progress:
        self.bar.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.update(self.task, completed=self.capture.size)
        self.bar.stop()

    def update(self) -> None:
        now = time.monotonic()
        if now - self.last < 0.2:
            return
        self.last = now
        self.bar.update(self.task, completed=min(self.capture.pos, self.capture.size))


class _NoProgress:
    def __enter__(self) -> _NoProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    def update(self) -> None:
        pass


def _progress(capture: Capture) -> _Progress | _NoProgress:
    """A bar when stderr is a terminal and the capture is large (and its size known), else nothing."""
    if sys.stderr.isatty() and capture.size >= PROGRESS_MIN_BYTES:
        return _Progress(capture)
    return _NoProgress()
