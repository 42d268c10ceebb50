"""A capture read as a replay script: the capture readers of ``xac1 decode``, the sniffer's analyzer.

``read_script`` opens the capture file(s) as ``xac1 decode`` does (``sniffer.capture_args``: the format
sniffed or given, ``--host-is``, the other direction's file of a per-direction format), has the
conversation judged by the analyzer (the one rulebook pairs each answer with its host line) and hands
every frame and junk record to ``xac1_proto.replay.ScriptBuilder``. ``load_script`` is the plug-in the
simulator finds under the entry-point group ``xac1_proto.replay_scripts`` (``xac1 sim --replay``,
``xac1sim://?replay=FILE``): the core names no sniffer.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass, field

from xac1_proto.replay import Answer, Script, ScriptBuilder

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
    """A script with what reading it found: the format, the capture's records (the sniffer's verdicts
    on the captured conversation) and the problems of the files."""

    script: Script
    format: str
    records: list[Record] = field(default_factory=list)
    report: Report = field(default_factory=Report)


def read_script(files: Sequence[str], input_format: str = "auto", host_is: str | None = None,
                samplerate: float | None = None, program: str = "xac1 replay",
                no_answer_timeout: float | None = None) -> CapturedScript:
    """Read ``files`` as one capture; CaptureError when nothing can be replayed from them.
    ``no_answer_timeout``: the analyzer's (as ``xac1 decode --timeout``): which line a late answer
    belongs to depends on it."""
    report = Report()
    sources: list[Source] = []
    args = argparse.Namespace(input_format=input_format, host_is=host_is, samplerate=samplerate)
    try:
        sources = open_sources(list(files), report)
        fmt, one_sided = choose_format(sources, args, report, program)
        if one_sided:
            raise CaptureError(f"{sources[0].name} holds one line direction only: give the other "
                               f"direction's file too (a replay needs both)")
        with Capture(sources, fmt, host_is=host_is, samplerate=samplerate, report=report) as capture:
            analyzer = Analyzer() if no_answer_timeout is None else Analyzer(no_answer_timeout)
            records: list[Record] = []
            for chunk in capture:
                report.give_up_after = None
                records += analyzer.feed(chunk)
            records += analyzer.close()
    except WrongFormat:
        why = report.looks_like or "too many problems before any line data"
        raise CaptureError(f"{', '.join(files)}: not a {input_format} capture ({why}); leave --input-format "
                           f"out to detect the format") from None
    except FormatError as exc:
        raise CaptureError(str(exc)) from None
    except OSError as exc:
        raise CaptureError(f"{exc.filename or ', '.join(files)}: {exc.strerror or exc}") from None
    finally:
        for src in sources:
            src.close()
    script = script_of(records)
    if not script.lines:
        raise CaptureError(f"{', '.join(files)}: no host line in this {fmt} capture: nothing to replay")
    return CapturedScript(script, fmt, records, report)


def script_of(records: Sequence[Record]) -> Script:
    """The script of an analyzer's records (frames and junk runs; missed answers need nothing)."""
    builder = ScriptBuilder()
    for r in records:
        if isinstance(r, FrameRecord):
            if r.dir == "host":
                builder.host(r.i, r.raw, r.t, r.t_last)
            else:
                builder.device(Answer(r.raw, r.header, r.frame, r.t, r.t_last), r.reply_to)
        elif isinstance(r, JunkRecord):
            if r.dir == "host":
                builder.host(r.i, r.raw, r.t, r.t)
            else:
                builder.device(Answer(r.raw, None, None, r.t, r.t), r.reply_to)
    return builder.build()


def load_script(files: Sequence[str], input_format: str = "auto", host_is: str | None = None) -> Script:
    """The entry point of ``xac1_proto.replay_scripts``: the script of a capture, or ValueError."""
    return read_script(files, input_format, host_is, program="xac1 sim").script
