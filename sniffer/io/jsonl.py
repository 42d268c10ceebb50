"""Readers for our own JSON lines: raw recordings (``sniffer.io.recording``) and decoded output.

How this works: a recording's first line is ``{"type":"recording",...}`` and each chunk line is read by
``recording.chunk_of``. A line comes whole (the source hands a long one over in pieces of the same
number); one longer than ``recording.LONGEST_LINE`` is one problem at its line and is not read.
Decoded output (``xac1 sniff/decode --format jsonl``) has one record a line: ``frame`` and ``junk``
records carry the bytes of their line (``raw``, hex) with the time of the first byte, so the chunks are
those records in order; ``timeout`` and ``summary`` lines are skipped (decoding again recomputes them).
Directions are stored as ``host``/``device``, so there is no side to choose: ``--host-is`` is not used.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Final

from xac1_proto.chunk import Chunk
from xac1_proto.recording import LONGEST_LINE, chunk_of, is_recording, load_line

from .base import Clock, Source, shown

FORMAT: Final = "jsonl"
DESCRIPTION: Final = "our JSON lines: a raw recording or decoded output"
HOST_DEFAULT: Final = "stored in the file (host/device)"
SUFFIXES: Final = (".jsonl", ".ndjson")
_RECORD_TYPES: Final = ("frame", "junk", "timeout", "summary")


def sniff(head: list[str]) -> int:
    if head and is_recording(head[0]):
        return 99
    for line in head[:3]:
        try:
            obj = json.loads(line)
        except ValueError:
            return 0
        if isinstance(obj, dict) and obj.get("type") in _RECORD_TYPES:
            return 95
    return 0


def read(src: Source, host_is: str | None = None) -> Iterator[Chunk]:
    lines = _whole_lines(src)
    first = next(lines, None)
    if first is None:
        src.report.problem(src.name, "empty file")
        return
    if is_recording(first[1]):
        yield from _recording(src, _chain([first], lines))
    else:
        yield from _decoded(src, _chain([first], lines))


def _whole_lines(src: Source) -> Iterator[tuple[int, str]]:
    """(number, text) of each line, its pieces joined; a line longer than ``LONGEST_LINE`` is reported
    once, at its number, and skipped (its pieces are not kept)."""
    number, size = 0, 0
    pieces: list[str] = []
    for n, piece in src.lines():
        if n != number:
            yield from _line(src, number, pieces, size)
            number, pieces, size = n, [], 0
        size += len(piece)
        if size <= LONGEST_LINE:
            pieces.append(piece)
    yield from _line(src, number, pieces, size)


def _line(src: Source, number: int, pieces: list[str], size: int) -> Iterator[tuple[int, str]]:
    if size > LONGEST_LINE:
        src.report.problem(src.where(number), f"a line of {size:,} characters, longer than any recording or "
                                              f"record line ({LONGEST_LINE:,} at most); not read", nlines=1)
    elif pieces:
        yield number, "".join(pieces)


def _recording(src: Source, lines: Iterator[tuple[int, str]]) -> Iterator[Chunk]:
    clock = Clock(src.report)
    for number, text in lines:
        if not text.strip():
            continue
        try:
            chunk = chunk_of(text)
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            src.report.problem(src.where(number), f"malformed recording line ({exc})", nlines=1)
            continue
        if chunk is None:
            continue
        t, error = chunk.t, chunk.error
        if t is not None and (isinstance(t, bool) or not isinstance(t, (int, float))):
            src.report.problem(src.name, f"chunk time {shown(str(t), 20)} is not a number; the bytes are "
                                         f"kept with the previous time")
            t = clock.last
        else:
            t = clock.check(t, src.name)
        if error is not None and not isinstance(error, str):
            error = shown(str(error), 40)
        yield Chunk(t, chunk.dir, chunk.data, error)


def _decoded(src: Source, lines: Iterator[tuple[int, str]]) -> Iterator[Chunk]:
    report = src.report
    clock = Clock(report)
    for number, text in lines:
        if not text.strip():
            continue
        try:
            obj = load_line(text)
            kind = obj.get("type")
            if kind in ("timeout", "summary"):
                continue
            if kind not in ("frame", "junk") or obj.get("dir") not in ("host", "device"):
                raise ValueError(f"not a frame or junk record (type {kind!r})")
            errors = obj.get("line_errors") or []
            t = obj.get("t")
            if t is not None and (isinstance(t, bool) or not isinstance(t, (int, float))):
                raise ValueError(f"time {shown(str(t), 20)} is not a number")
            error = errors[0] if isinstance(errors, list) and errors else None
            if error is not None and not isinstance(error, str):
                raise ValueError("line_errors must be a list of strings")
            t = clock.check(t, src.where(number))
            yield Chunk(t, obj["dir"], bytes.fromhex(obj["raw"]), error)
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            report.problem(src.where(number), f"malformed decoded record ({exc})", nlines=1)


def _chain(head: list[tuple[int, str]], lines: Iterator[tuple[int, str]]) -> Iterator[tuple[int, str]]:
    yield from head
    yield from lines
