"""Reader for raw binary captures: the bytes of one line direction a file, no timestamps.

How this works: with two files (one per direction) there is no time to merge by, so the bytes are
paired by order, as a strict request/answer protocol allows: one line (up to and including LF) from
the host file, then one from the device file, and so on; when one file runs out the rest of the other
follows. Chunks have ``t=None``, so timing checks (no-answer) cannot run; a command left unanswered
shifts the pairing, so ``no-answer`` lands on the last command (said in a note). A single file is one
side. A file not ending with LF was cut inside a frame (reported with its byte offset).

Host side default: a file whose name says ``host`` (``device`` marks the other), else the first file
given; ``--host-is`` takes a file name.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Final

from xac1_proto.chunk import Chunk

from .base import Sides, Source

FORMAT: Final = "raw"
DESCRIPTION: Final = "raw bytes, one file per direction (paired by order, no times)"
HOST_DEFAULT: Final = "the file named host, else the first file given"
SUFFIXES: Final = (".bin", ".raw")
BINARY: Final = True
MULTI_FILE: Final = True
_LINE_CAP: Final = 4096


def _lines(src: Source) -> Iterator[bytes]:
    buf = b""
    while True:
        block = src.read(_LINE_CAP)
        if not block:
            break
        buf += block
        while True:
            i = buf.find(b"\n")
            if i < 0:
                break
            yield buf[: i + 1]
            buf = buf[i + 1:]
        if len(buf) >= _LINE_CAP:
            yield buf
            buf = b""
    if buf:
        if not buf.endswith(b"\n"):
            src.report.problem(f"{src.name}@{src.pos - len(buf)}", f"the file ends with {len(buf)} byte(s) "
                               f"and no LF: the capture was cut short inside a frame, or a frame was "
                               f"left unfinished")
        yield buf


def read_files(sources: list[Source], host_is: str | None = None) -> Iterator[Chunk]:
    """Chunks of one or two raw files, alternating line by line starting with the host."""
    sides = Sides(FORMAT, host_is)
    report = sources[0].report
    if len(sources) > 2:
        for extra in sources[2:]:
            report.problem(extra.name, "raw: only two files (host and device) are read; this one is "
                                       "skipped", nbytes=extra.size)
        sources = sources[:2]
    report.note("raw files have no time: lines are paired one host line, then one device line, so a "
                "command left unanswered shifts the later answers and shows as no-answer on the last "
                "command; the other checks hold")
    dirs = [(src, sides.direction(src.name)) for src in sources]
    sides.check(report, ", ".join(s.name for s in sources))
    dirs.sort(key=lambda pair: pair[1] != "host")
    streams = [(_lines(src), d) for src, d in dirs]
    while streams:
        for item in list(streams):
            it, d = item
            line = next(it, None)
            if line is None:
                streams.remove(item)
                continue
            assert d is not None
            yield Chunk(None, d, line)
