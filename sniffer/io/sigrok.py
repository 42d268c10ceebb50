"""Reader for sigrok-cli UART decoder annotations (``-P uart:... -A uart=rx-data``).

How this works: each line is one annotation, ``[START-END ]INSTANCE: [CLASS: ]TEXT``: sample numbers
with ``--protocol-decoder-samplenum``, the decoder instance (``uart-1``, ``uart-2``: one per ``-P``),
the class with ``--protocol-decoder-ann-class`` (``rx-data``, ``tx-data``, ``rx-frame-err``...), then
the annotation text, quoted in some sigrok-cli versions. Data bytes are hex (``30``, the decoder's
default ``format=hex``) or ASCII (``format=ascii``: ``0``, ``[0D]``); a decoder instance prints one
format, so an annotation in the other one is a damaged line. A ``Frame error`` or
``Parity error`` annotation marks the last byte of that side as damaged on the wire (Chunk.error).
Sample numbers become seconds with ``--samplerate HZ``; without it the bytes have no time.

Sides: with two or more decoder instances each instance is a line, the host being ``uart-1`` by
default. With one instance the annotation class tells the lines apart, the host being ``tx-data`` by
default (``-A uart=rx-data:tx-data`` with ``--protocol-decoder-ann-class``). ``--host-is`` takes an
instance (``uart-2``) or a class (``rx-data``).
"""

from __future__ import annotations

import heapq
import math
import re
import statistics
from collections.abc import Iterator
from itertools import islice
from typing import Final

from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk, Direction

from .base import Clock, FormatError, Report, Source, numbered_lines, shown

FORMAT: Final = "sigrok"
DESCRIPTION: Final = "sigrok-cli UART annotations (-A uart=rx-data)"
HOST_DEFAULT: Final = "uart-1 (two instances) or tx-data (one instance)"
SUFFIXES: Final = (".sigrok",)

_LINE: Final = re.compile(r"(?:(\d{1,18})-(\d{1,18}) )?([A-Za-z][\w.]*-\d{1,9}): "
                          r"(?:([a-z][a-z0-9-]*): )?(.*)")
_ERRORS: Final = {"frame error": "UART framing error", "parity error": "UART parity error"}
_DATA_BITS: Final = spec.BITS_PER_BYTE - 2  # 8N1 less start and stop bits
_PRESCAN: Final = 2000  # lines looked at to learn the instances and classes


def sniff(head: list[str]) -> int:
    rows = [line for line in head if line.strip()]
    good = [r for r in rows if _LINE.fullmatch(r)]
    return 80 if good and len(good) >= max(1, len(rows) * 2 // 3) else 0


def _byte(text: str) -> int | None:
    """The data byte an annotation text shows (hex, or ASCII with [XX] escapes), else None."""
    text = text.strip()
    if len(text) >= 2 and text[0] == text[-1] == '"':
        text = text[1:-1]
    if re.fullmatch(r"[0-9A-Fa-f]{2}", text):
        return int(text, 16)
    if re.fullmatch(r"\[[0-9A-Fa-f]{2}\]", text):
        return int(text[1:3], 16)
    if len(text) == 1:
        return ord(text) & 0xFF
    return None


def _first_text(rest: str) -> str:
    """The first (longest) annotation string: ``"30" "30"`` -> ``30``."""
    rest = rest.strip()
    if rest.startswith('"'):
        end = rest.find('"', 1)
        return rest[: end + 1] if end > 0 else rest
    return rest


def read(src: Source, host_is: str | None = None, samplerate: float | None = None) -> Iterator[Chunk]:
    report = src.report
    if samplerate is not None and not (math.isfinite(samplerate) and samplerate > 0):
        raise FormatError(f"--samplerate {samplerate}: must be a positive rate in Hz")
    instances, classes, inferred = _prescan(src)
    if samplerate is None and inferred is not None:
        samplerate = inferred
        report.note(f"{src.name}: no --samplerate given; {inferred:g} Hz inferred from the byte lengths "
                    f"at the spec's {spec.BAUD} baud")
    if host_is is not None and host_is not in instances | classes | {"tx-data", "rx-data"}:
        report.problem(src.name, f"--host-is {host_is!r} matches no decoder instance or class of this "
                                 f"file (instances: {', '.join(sorted(instances)) or 'none'}; classes: "
                                 f"{', '.join(sorted(classes)) or 'not shown'})")
    if len(instances) > 1 and samplerate is not None:
        # sigrok-cli prints each decoder instance's annotations block by block, not in time order
        # across instances: read the file once per instance and merge by time (constant memory).
        first, *others = sorted(instances, key=_instance_number)
        passes = [_pass(src, src.lines(), host_is, samplerate, instances, classes, only=first,
                        report_all=True)]
        passes += [_pass(src, _extra_lines(src), host_is, samplerate, instances, classes, only=other)
                   for other in others]
        yield from heapq.merge(*passes, key=lambda c: c.t if c.t is not None else -1.0)
    else:
        yield from _pass(src, src.lines(), host_is, samplerate, instances, classes, only=None,
                         report_all=True)


def _extra_lines(src: Source) -> Iterator[tuple[int, str]]:
    with src.reopen() as f:
        yield from numbered_lines(f, src.max_line)


def _annotations(src: Source, lines: Iterator[tuple[int, str]], instances: set[str], only: str | None,
                 report_all: bool) -> Iterator[tuple[int, re.Match[str]]]:
    """The line tokenizer: (line number, match) of each annotation line of this pass; a line that is
    no annotation is reported (once, by the pass that reports everything)."""
    for number, line in lines:
        if not line.strip():
            continue
        m = _LINE.fullmatch(line)
        if not m:
            if report_all:
                src.report.problem(src.where(number), f"not a sigrok-cli annotation line: {shown(line)}",
                                   nlines=1)
            continue
        instance = m.group(3)
        if only is not None and instance != only and (instance in instances or not report_all):
            continue
        yield number, m


def _pass(src: Source, lines: Iterator[tuple[int, str]], host_is: str | None, samplerate: float | None,
          instances: set[str], classes: set[str], only: str | None,
          report_all: bool = False) -> Iterator[Chunk]:
    """The chunk builder of one reading of the file (of one decoder instance when ``only`` is given):
    each data byte held back one step (``_LastBytes``) so that a following error annotation can mark it."""
    report = src.report
    direction = _Directions(instances, host_is)
    saw_samples = False
    held = _LastBytes()
    forms: dict[str, str] = {}  # instance -> "hex" or "ascii", from its first data annotation
    clock = Clock(report if report_all or only is None else _Quiet())
    for number, m in _annotations(src, lines, instances, only, report_all):
        start, _end, instance, cls, rest = m.groups()
        d = direction(instance, cls)
        text = _first_text(rest)
        if (mark := _error_mark(text, cls)) is not None:
            yield held.marked(d, mark)
            continue
        if cls is not None and not cls.endswith("-data"):
            continue  # start/stop bits, warnings: not data
        value = _byte(text)
        problem = _data_problem(text, value, instance, forms)
        if problem is not None:
            if report_all or (only == instance and value is not None):
                report.problem(src.where(number), problem, nlines=1)
            continue
        assert value is not None
        saw_samples = saw_samples or start is not None
        t = None if start is None or samplerate is None else \
            clock.check(int(start) / samplerate, src.where(number))
        yield from held.hold(Chunk(t, d, bytes([value])))
    yield from held.bytes.values()
    if saw_samples and samplerate is None and report_all:
        report.note(f"{src.name}: sample numbers present but no --samplerate given: bytes have no time, "
                    f"so timing checks (no-answer) are skipped")


def _error_mark(text: str, cls: str | None) -> str | None:
    """The UART error an annotation says (``Frame error``, ``Parity error``, a ``*-err`` class), else
    None."""
    error = _ERRORS.get(text.strip('"').lower())
    if error is not None or (cls or "").endswith("-err"):
        return error or f"UART {cls}"
    return None


class _LastBytes:
    """The last data byte of each line, held back so that an error annotation after it can mark it."""

    def __init__(self) -> None:
        self.bytes: dict[Direction, Chunk] = {}

    def marked(self, d: Direction, mark: str) -> Chunk:
        """An error annotation on line ``d``: the byte held of that line marked (a chunk without bytes
        when none is held)."""
        prev = self.bytes.pop(d, None)
        return Chunk(prev.t if prev else None, d, prev.data if prev else b"", mark)

    def hold(self, byte: Chunk) -> list[Chunk]:
        """Hold a data byte; the bytes held before it, handed on (its line's, then the other line's)."""
        done = []
        if (prev := self.bytes.pop(byte.dir, None)) is not None:
            done.append(prev)
        done.extend(self.bytes.values())
        self.bytes = {byte.dir: byte}
        return done


def _data_problem(text: str, value: int | None, instance: str, forms: dict[str, str]) -> str | None:
    """Why a data annotation cannot be read as a byte (None when it can)."""
    if value is None:
        return f"annotation {shown(text)} is not a data byte (show only the data class: -A uart=rx-data)"
    form = "hex" if re.fullmatch(r'"?[0-9A-Fa-f]{2}"?', text.strip()) else "ascii"
    if forms.setdefault(instance, form) != form:
        return (f"annotation {shown(text)} is {form} but {instance}'s earlier ones are {forms[instance]} "
                f"(one decoder prints one format): the line is damaged, skipped")
    return None


class _Directions:
    """Which line an annotation is on: by decoder instance when there are several (host ``uart-1``),
    else by class (host ``tx-data``); ``--host-is`` names either."""

    def __init__(self, instances: set[str], host_is: str | None) -> None:
        self.by_instance = len(instances) > 1
        self.first = min(instances, key=_instance_number) if instances else ""
        self.host_is = host_is

    def __call__(self, instance: str, cls: str | None) -> Direction:
        if self.by_instance:
            key, default = instance, self.first
        else:
            key = "tx-data" if (cls or "rx-data").startswith("tx") else "rx-data"
            default = "tx-data"
        if self.host_is is not None:
            return HOST if self.host_is in (instance, key, cls) else DEVICE
        return HOST if key == default else DEVICE


class _Quiet(Report):
    """A report for the extra passes over the file: the first pass reports everything once."""

    def problem(self, where: str, message: str, *, nbytes: int = 0, nlines: int = 0) -> None:
        pass


def _instance_number(name: str) -> int:
    return int(name.rsplit("-", 1)[1])


def _prescan(src: Source) -> tuple[set[str], set[str], float | None]:
    """Instances, classes and (from data bytes' sample spans) the sample rate implied by the spec's baud
    rate, from the first lines (read separately, so streaming is not disturbed)."""
    instances: set[str] = set()
    classes: set[str] = set()
    spans: list[int] = []
    with src.reopen() as f:
        for _number, line in islice(numbered_lines(f, src.max_line), _PRESCAN):
            m = _LINE.fullmatch(line)
            if m:
                instances.add(m.group(3))
                if m.group(4):
                    classes.add(m.group(4))
                if m.group(1) is not None and (m.group(4) or "-data").endswith("-data") and \
                        _byte(_first_text(m.group(5))) is not None:
                    spans.append(int(m.group(2)) - int(m.group(1)))
    rate = None
    if spans:
        # a data annotation spans the 8 data bits
        rate = round(statistics.median(spans) / _DATA_BITS * spec.BAUD)
    return instances, classes, rate if rate and rate > 0 else None
