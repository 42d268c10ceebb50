"""Format name -> reader, content sniffing, and the chunk stream of one or more capture files.

How this works: each reader module names itself (``FORMAT``), says which side is the host by default
(``HOST_DEFAULT``), gives suffix hints (``SUFFIXES``) and a ``sniff`` of the first text lines (or
``sniff_bytes`` of the first bytes for binary formats) returning a confidence 0-100. ``detect`` scores
every format on every file; a suffix hint adds a little. ``auto`` picks the best format when it is
clearly ahead, else ``FormatError`` lists what it considered. ``chunks`` opens the files and merges
their chunks by time (readers of formats with one file per direction share one ``Sides``); raw files,
having no time, are paired by order.
"""

from __future__ import annotations

import heapq
import itertools
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Final

from xac1_proto.chunk import Chunk

from . import interceptty, jpnevulator, jsonl, pcap, raw, saleae, sigrok, socat, spy
from .base import HEAD_BYTES, FormatError, Report, Sides, Source, head_lines

READERS: Final[dict[str, ModuleType]] = {m.FORMAT: m for m in (
    jsonl, pcap, socat, spy, interceptty, jpnevulator, saleae, sigrok, raw)}
NAMES: Final = tuple(READERS)
SURE: Final = 50  # a score at least this high, clearly ahead of the next, decides alone
SUFFIX_BONUS: Final = 10
RAW_FALLBACK: Final = 30


def _score(module: ModuleType, path: Path, first: bytes) -> int:
    score = 0
    if hasattr(module, "sniff_bytes"):
        score = module.sniff_bytes(first)
    elif hasattr(module, "sniff"):
        score = module.sniff(first.decode("latin-1").splitlines()[:20])
    if module is raw:
        score = _raw_score(first)
    if score and path.suffix.lower() in module.SUFFIXES:
        score += SUFFIX_BONUS
    elif not score and module is raw and path.suffix.lower() in module.SUFFIXES:
        score = RAW_FALLBACK + SUFFIX_BONUS
    return score


def _raw_score(first: bytes) -> int:
    """Raw XA-C1 traffic: bytes that look like frames (start with the digit 0, CR LF ends)."""
    if not first:
        return 0
    lines = [line for line in first.split(b"\n") if line]
    framey = sum(1 for line in lines if line[:1] in (b"0", b"O"))
    return RAW_FALLBACK if framey and framey * 3 >= len(lines) * 2 else 0


@dataclass(frozen=True)
class Detection:
    name: str
    considered: tuple[tuple[str, int], ...]  # every format with a non-zero score, best first


def _head(p: str | Source) -> tuple[str, Path, bytes]:
    if isinstance(p, Source):
        return p.name, p.path, p.head()
    with open(p, "rb") as f:
        return p, Path(p), f.read(HEAD_BYTES)


def detect(paths: list[str] | list[Source]) -> Detection:
    """The format of these files, or FormatError naming the formats considered. Given ``Source``s, it
    sniffs their buffered heads, so a pipe is not consumed."""
    names, totals = _scores(paths)
    ranked = sorted(((name, min(scores)) for name, scores in totals.items()), key=lambda x: -x[1])
    considered = tuple((n, s) for n, s in ranked if s > 0)
    best = _decided(considered)
    if best is None:
        if len(names) > 1:
            _refuse_mixed(names, totals)
        listed = ", ".join(f"{n} ({s})" for n, s in considered) or "none matched"
        raise FormatError(f"{', '.join(names)}: cannot tell the capture format; considered: {listed}. "
                          f"Give --input-format, one of: {', '.join(NAMES)}")
    return Detection(best, considered)


def _scores(paths: list[str] | list[Source]) -> tuple[list[str], dict[str, list[int]]]:
    """The files' names and every format's score on each file (an empty file is refused)."""
    totals: dict[str, list[int]] = {name: [] for name in NAMES}
    names: list[str] = []
    for p in paths:
        name, path, first = _head(p)
        names.append(name)
        if not first:
            raise FormatError(f"{name}: the file is empty")
        for fmt, module in READERS.items():
            totals[fmt].append(_score(module, path, first))
    return names, totals


def _decided(considered: tuple[tuple[str, int], ...]) -> str | None:
    """The format clearly ahead (a sure score, at least 10 above the next), or raw when only raw fits;
    None when the scores do not decide."""
    if not considered:
        return None
    best, score = considered[0]
    runner_up = considered[1][1] if len(considered) > 1 else 0
    if len(considered) == 1 and best == "raw" or score >= SURE and score - runner_up >= 10:
        return best
    return None


def _refuse_mixed(names: list[str], totals: dict[str, list[int]]) -> None:
    """Files that are each surely a capture, of different formats: refused, saying which is which."""
    per_file = [_best_of(totals, i) for i in range(len(names))]
    if len({fmt for fmt, _score in per_file}) > 1 and all(sc >= SURE for _fmt, sc in per_file):
        each = "; ".join(f"{n} is {fmt}" for n, (fmt, _sc) in zip(names, per_file, strict=True))
        raise FormatError(f"the files are captures of different formats: {each}. Decode each "
                          f"on its own (one command per file), or name one format with "
                          f"--input-format")


def _best_of(totals: dict[str, list[int]], i: int) -> tuple[str, int]:
    """The best format of the i-th file alone, with its score."""
    fmt = max(NAMES, key=lambda n: totals[n][i])
    return fmt, totals[fmt][i]


def sniff_one(src: Source) -> str | None:
    """The format one file looks like on its own (a sure score), for messages; None when unsure."""
    try:
        return detect([src]).name
    except FormatError:
        return None


class Capture:
    """The chunks of one or more files of one format, with their sources (for progress) and report."""

    def __init__(self, paths: list[str] | list[Source], fmt: str, host_is: str | None = None,
                 samplerate: float | None = None, report: Report | None = None) -> None:
        if fmt not in READERS:
            raise FormatError(f"unknown input format {fmt!r}; one of: {', '.join(NAMES)}")
        self.format = fmt
        self.module = READERS[fmt]
        self.report = report or Report()
        self.sources = [p if isinstance(p, Source) else Source(p, self.report) for p in paths]
        for src in self.sources:
            src.report = self.report
        self.host_is = host_is
        self.samplerate = samplerate
        if samplerate is not None and fmt != "sigrok":
            self.report.note(f"--samplerate applies to sigrok annotations only; ignored for {fmt}")

    @property
    def size(self) -> int:
        return sum(s.size for s in self.sources)

    @property
    def pos(self) -> int:
        return sum(s.pos for s in self.sources)

    def _one(self, src: Source, sides: Sides | None) -> Iterator[Chunk]:
        kwargs: dict[str, Any] = {}
        if self.module is sigrok:
            kwargs["samplerate"] = self.samplerate
        if self.module is saleae:
            kwargs.update(sides=sides, multi_file=len(self.sources) > 1)
        return self.module.read(src, self.host_is, **kwargs)

    def __iter__(self) -> Iterator[Chunk]:
        """The chunks of every source (merged by time when there are several), then the end checks. The
        reader's own iterator comes out as it is (``chain``): no generator hands each chunk on."""
        if self.module is raw:
            return raw.read_files(self.sources, self.host_is)
        sides = Sides(self.format, self.host_is) if getattr(self.module, "MULTI_FILE", False) else None
        streams = [self._one(src, sides) for src in self.sources]
        merged = streams[0] if len(streams) == 1 else heapq.merge(*streams, key=_time_key)
        return itertools.chain(merged, self._ended(sides))

    def _ended(self, sides: Sides | None) -> Iterator[Chunk]:
        """No chunk: the checks at the end of the sources (a generator, run when they are all read)."""
        for src in self.sources:
            src.check_end()
        if sides is not None:
            sides.check(self.report, ", ".join(s.name for s in self.sources))
        yield from ()

    def close(self) -> None:
        for s in self.sources:
            s.close()

    def __enter__(self) -> Capture:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _time_key(chunk: Chunk) -> float:
    return chunk.t if chunk.t is not None else float("-inf")


def describe() -> list[tuple[str, str, str]]:
    """(format, what it reads, default host side) for help texts."""
    return [(m.FORMAT, m.DESCRIPTION, m.HOST_DEFAULT) for m in READERS.values()]


def is_readable(path: str) -> bool:
    return os.path.isfile(path) and os.access(path, os.R_OK)


__all__ = ["READERS", "NAMES", "Capture", "Detection", "FormatError", "Report", "detect", "describe",
           "head_lines", "is_readable", "sniff_one"]
