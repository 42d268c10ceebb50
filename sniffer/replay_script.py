"""A capture read as a replay script: the capture readers of ``xac1 decode``, the sniffer's analyzer.

``ScriptStream`` opens the capture file(s) as ``xac1 decode`` does (``sniffer.capture_args``: the format
sniffed or given, ``--host-is``, the other direction's file of a per-direction format), has the
conversation judged by the analyzer (the one rulebook pairs each answer with its host line) and hands
every frame and junk record to ``xac1_proto.replay.ScriptBuilder``, batch by batch as decode reads;
whenever the conversation is quiet (no answer awaited, no device bytes being framed) the lines before
the last one are final and go out, so a capture of any size is read in flat memory (``xac1 replay
--dry-run``). ``read_script`` holds them all (the device side and the replay itself). ``load_script``
is the plug-in the simulator finds under the entry-point group ``xac1_proto.replay_scripts`` (``xac1
sim --replay``, ``xac1sim://?replay=FILE``): the core names no sniffer.
"""

from __future__ import annotations

import argparse
import itertools
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field

from xac1_proto.chunk import DEVICE
from xac1_proto.replay import Answer, CapturedLine, Script, ScriptBuilder

from .analyzer import Analyzer
from .capture_args import choose_format, open_sources
from .io.base import FormatError, Report, Source, WrongFormat
from .io.registry import Capture
from .records import FrameRecord, JunkRecord, Record


class CaptureError(ValueError):
    """The capture cannot be read (missing file, unknown or wrong format, no line data); the message
    says which file and why."""


@dataclass
class CapturedScript:
    """A script with what reading it found: the format and the problems of the files."""

    script: Script
    format: str
    report: Report = field(default_factory=Report)


class ScriptStream:
    """A capture read as a script line by line (``for line in stream``), as ``xac1 decode`` reads it:
    memory stays flat whatever the capture's size (``ScriptBuilder`` holds only the lines since the
    conversation was last quiet). ``format`` and ``report`` are known once it is open; ``lead`` and
    ``count`` once it has been read. Iterating raises CaptureError when the capture turns out unreadable
    or holds no host line. A context manager: it closes the files."""

    def __init__(self, files: Sequence[str], input_format: str = "auto", host_is: str | None = None,
                 samplerate: float | None = None, program: str = "xac1 replay",
                 no_answer_timeout: float | None = None) -> None:
        self.files = list(files)
        self.input_format = input_format
        self.report = Report()
        self.count = 0
        self._builder = ScriptBuilder()
        self._analyzer = Analyzer() if no_answer_timeout is None else Analyzer(no_answer_timeout)
        self._sources: list[Source] = []
        args = argparse.Namespace(input_format=input_format, host_is=host_is, samplerate=samplerate)
        with self._readable():
            try:
                self._sources = open_sources(self.files, self.report)
                self.format, one_sided = choose_format(self._sources, args, self.report, program)
                if one_sided:
                    raise CaptureError(f"{self._sources[0].name} holds one line direction only: give the "
                                       f"other direction's file too (a replay needs both)")
                self._capture = Capture(self._sources, self.format, host_is=host_is, samplerate=samplerate,
                                        report=self.report)
            except BaseException:
                self.close()
                raise

    @property
    def lead(self) -> tuple[Answer, ...]:
        return self._builder.lead

    def __iter__(self) -> Iterator[CapturedLine]:
        analyzer, builder = self._analyzer, self._builder
        with self._readable():
            chunks = iter(self._capture)
            first = next(chunks, None)
            self.report.give_up_after = None  # data came (or none will): the format reads
            chunks = itertools.chain(() if first is None else (first,), chunks)
            records: list[Record] = []
            device_framed = 0  # device bytes in the records so far
            while analyzer.feed_many(chunks, records):
                device_framed += add_records(builder, records)
                records.clear()
                if not analyzer.waiting and device_framed == analyzer.bytes_in(DEVICE):
                    yield from self._counted(builder.settled())
            add_records(builder, analyzer.close())
            yield from self._counted(builder.finish())
        if not self.count:
            raise CaptureError(f"{', '.join(self.files)}: no host line in this {self.format} capture: "
                               f"nothing to replay")

    def _counted(self, lines: list[CapturedLine]) -> list[CapturedLine]:
        self.count += len(lines)
        return lines

    @contextmanager
    def _readable(self) -> Iterator[None]:
        """The readers' errors as CaptureError, naming the files."""
        try:
            yield
        except WrongFormat:
            why = self.report.looks_like or "too many problems before any line data"
            raise CaptureError(f"{', '.join(self.files)}: not a {self.input_format} capture ({why}); leave "
                               f"--input-format out to detect the format") from None
        except FormatError as exc:
            raise CaptureError(str(exc)) from None
        except OSError as exc:
            raise CaptureError(f"{exc.filename or ', '.join(self.files)}: {exc.strerror or exc}") from None

    def close(self) -> None:
        for src in self._sources:
            src.close()

    def __enter__(self) -> ScriptStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_script(files: Sequence[str], input_format: str = "auto", host_is: str | None = None,
                samplerate: float | None = None, program: str = "xac1 replay",
                no_answer_timeout: float | None = None) -> CapturedScript:
    """Read ``files`` as one capture, every line held (the device side and the replay report need them
    all; ``ScriptStream`` reads line by line); CaptureError when nothing can be replayed from them.
    ``no_answer_timeout``: the analyzer's (as ``xac1 decode --timeout``): which line a late answer
    belongs to depends on it."""
    with ScriptStream(files, input_format, host_is, samplerate, program, no_answer_timeout) as stream:
        lines = tuple(stream)
        return CapturedScript(Script(lines, stream.lead), stream.format, stream.report)


def add_records(builder: ScriptBuilder, records: Sequence[Record]) -> int:
    """Hand the frame and junk records to ``builder``; the device bytes they hold."""
    device = 0
    for r in records:
        if isinstance(r, FrameRecord):
            if r.dir == "host":
                builder.host(r.i, r.raw, r.t, r.t_last)
            else:
                builder.device(Answer(r.raw, r.header, r.frame, r.t, r.t_last), r.reply_to)
                device += len(r.raw)
        elif isinstance(r, JunkRecord):
            if r.dir == "host":
                builder.host(r.i, r.raw, r.t, r.t)
            else:
                builder.device(Answer(r.raw, None, None, r.t, r.t), r.reply_to)
                device += len(r.raw)
    return device


def script_of(records: Sequence[Record]) -> Script:
    """The script of an analyzer's records (frames and junk runs; missed answers need nothing)."""
    builder = ScriptBuilder()
    add_records(builder, records)
    return builder.build()


def load_script(files: Sequence[str], input_format: str = "auto", host_is: str | None = None) -> Script:
    """The entry point of ``xac1_proto.replay_scripts``: the script of a capture, or ValueError."""
    return read_script(files, input_format, host_is, program="xac1 sim").script
