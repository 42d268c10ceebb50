"""The fast lane's second memo: clean exchanges kept by the part of the knowledge they read.

``sniffer.fastlane`` keeps the exchanges the engine judged clean by the *whole* knowledge they went in
with, so one changed fact (a point no longer known after a garbled answer) leaves every exchange to be
judged again, even those that never look at it. This module watches the engine (``Tracer``) while it
judges an exchange on the full path and notes which facts and which points it read and which it wrote;
``ReadsMemo`` keeps the exchange by the values of what it read (``Reads``) with the values it left in
what it wrote (``Writes``). The same command and answer bytes, from the quiet state, with the same
values in what was read, get the same records and leave the same values in what was written: the
engine judges from the bytes, its own state (quiet: pinned by the lane's checks) and what it reads of
the knowledge, and everything it reads of the knowledge goes through the traced object.

How the engine is watched: for the duration of one ``Analyzer._feed`` the knowledge's class is a
subclass of ``Knowledge`` that records every field read (``__getattribute__``) and written
(``__setattr__``), and its ``points`` is a ``dict`` subclass that records every key read or written.
Whatever else is done to ``points`` as a whole (iteration, length, copying, comparing) or to the
knowledge as a whole (``__dict__``) marks the trace ``whole``: such an exchange is not kept here. Both
are put back, the same objects, before the call returns, however it ends. A change to ``Knowledge`` that
adds a mutable field other than ``points`` stops the fast lane's import (``sniffer.fastlane``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Final

from xac1_proto.conversation import Knowledge

from .records import FrameRecord

FIELDS: Final = frozenset(f.name for f in dataclasses.fields(Knowledge)) - {"points"}
MISSING: Final = object()  # a point that is not in ``points``
VARIANTS: Final = 8  # kept exchanges for one command's bytes (or one answer's), by what they read
ENTRIES: Final = 4096  # kept commands and answers in all (a record each); past it the memo starts again


class Trace:
    """What the engine read and wrote of the knowledge during one call (``Tracer.watching``)."""

    __slots__ = ("reads", "writes", "point_reads", "point_writes", "whole")

    def __init__(self) -> None:
        self.reads: set[str] = set()
        self.writes: set[str] = set()
        self.point_reads: set[Any] = set()
        self.point_writes: set[Any] = set()
        self.whole = False  # something read or changed it as a whole: not kept by parts

    @property
    def wrote(self) -> bool:
        return bool(self.writes or self.point_writes or self.whole)


class _Points(dict):
    """``Knowledge.points`` while traced: a key read or written is noted; anything on the whole dict is
    ``whole``."""

    trace: Trace  # set on the subclass each ``Tracer`` makes

    def get(self, key: Any, default: Any = None) -> Any:
        self.trace.point_reads.add(key)
        return dict.get(self, key, default)

    def __getitem__(self, key: Any) -> Any:
        self.trace.point_reads.add(key)
        return dict.__getitem__(self, key)

    def __contains__(self, key: object) -> bool:
        self.trace.point_reads.add(key)
        return dict.__contains__(self, key)

    def __setitem__(self, key: Any, value: Any) -> None:
        self.trace.point_writes.add(key)
        dict.__setitem__(self, key, value)

    def __delitem__(self, key: Any) -> None:
        self.trace.point_reads.add(key)  # it raises when the key is missing: the outcome depends on it
        self.trace.point_writes.add(key)
        dict.__delitem__(self, key)

    def pop(self, key: Any, *default: Any) -> Any:
        self.trace.point_reads.add(key)
        self.trace.point_writes.add(key)
        return dict.pop(self, key, *default)

    def setdefault(self, key: Any, default: Any = None) -> Any:
        self.trace.point_reads.add(key)
        self.trace.point_writes.add(key)
        return dict.setdefault(self, key, default)


def _whole(name: str) -> Any:
    """A dict method that reads or changes every point: noted as ``whole``, then done."""
    method = getattr(dict, name)

    def whole(self: _Points, *args: Any, **kwargs: Any) -> Any:
        self.trace.whole = True
        return method(self, *args, **kwargs)

    whole.__name__ = name
    return whole


for _name in ("__iter__", "__len__", "__eq__", "__ne__", "__repr__", "__reversed__", "__or__", "__ior__",
              "__ror__", "keys", "values", "items", "copy", "update", "clear", "popitem", "__reduce__",
              "__reduce_ex__", "__sizeof__"):
    setattr(_Points, _name, _whole(_name))
_Points.__hash__ = None


class Tracer:
    """Watches one engine's knowledge (see the module docstring); one per fast lane."""

    def __init__(self) -> None:
        self.trace = Trace()
        tracer = self

        class Watched(Knowledge):
            def __getattribute__(self, name: str) -> Any:
                if name in FIELDS:
                    tracer.trace.reads.add(name)
                elif name == "__dict__":
                    tracer.trace.whole = True
                return object.__getattribute__(self, name)

            def __setattr__(self, name: str, value: Any) -> None:
                if name in FIELDS:
                    tracer.trace.writes.add(name)
                elif name == "points":
                    tracer.trace.whole = True
                object.__setattr__(self, name, value)

        class Points(_Points):
            pass

        self._class = Watched
        self._points = Points

    @contextmanager
    def watching(self, k: Knowledge) -> Iterator[Trace]:
        """Trace ``k`` (a plain ``Knowledge``) during the ``with`` block; it is plain again afterwards,
        with the same ``points`` dict holding what the block left."""
        trace = self.trace = Trace()
        self._points.trace = trace
        points = k.points
        watched = self._points(points)
        k.__dict__["points"] = watched
        k.__class__ = self._class
        try:
            yield trace
        finally:
            k.__class__ = Knowledge
            left = k.__dict__["points"]
            if left is not points:
                if left is watched:
                    points.clear()
                    points.update(dict.items(watched))
                else:  # the block set another dict (``whole``): keep it, plain
                    points = dict(left)
                k.__dict__["points"] = points


class Reads:
    """What an exchange read, with the values it found: facts by name, points by number (``MISSING``:
    not there)."""

    __slots__ = ("facts", "points")

    def __init__(self, facts: tuple[tuple[str, Any], ...], points: tuple[tuple[Any, Any], ...]) -> None:
        self.facts = facts
        self.points = points

    def hold(self, k: Knowledge) -> bool:
        """Does ``k`` hold those values?"""
        for name, value in self.facts:
            now = getattr(k, name)
            if now is not value and now != value:
                return False
        if self.points:
            get = k.points.get
            for n, value in self.points:
                now = get(n, MISSING)
                if now is not value and (now is MISSING or value is MISSING or now != value):
                    return False
        return True


class Writes:
    """What an exchange left in what it wrote: facts by name, points by number (``MISSING``: dropped)."""

    __slots__ = ("facts", "points")

    def __init__(self, facts: tuple[tuple[str, Any], ...], points: tuple[tuple[Any, Any], ...]) -> None:
        self.facts = facts
        self.points = points

    def apply(self, k: Knowledge) -> None:
        for name, value in self.facts:
            setattr(k, name, value)
        points = k.points
        for n, value in self.points:
            if value is MISSING:
                points.pop(n, None)
            else:
                points[n] = value


class Answer:
    """A kept answer to a ``Command``: its record (a template), what it read and what it left."""

    __slots__ = ("record", "reads", "writes")

    def __init__(self, record: FrameRecord, reads: Reads, writes: Writes) -> None:
        self.record = record
        self.reads = reads
        self.writes = writes


class Command:
    """A kept command: its record (a template), the answer window it was given, what it read, and the
    answers seen to it, by their bytes, each a few variants by what they read."""

    __slots__ = ("host", "window", "reads", "answers")

    def __init__(self, host: FrameRecord, window: float, reads: Reads) -> None:
        self.host = host
        self.window = window
        self.reads = reads
        self.answers: dict[bytes, list[Answer]] = {}

    def answer(self, data: bytes, k: Knowledge) -> Answer | None:
        """The kept answer of these bytes whose reads ``k`` holds."""
        for answer in self.answers.get(data, ()):
            if answer.reads.hold(k):
                return answer
        return None


def _values(names: set[str], point_numbers: set[Any], before: tuple[Any, ...]) -> Reads:
    """The values of these facts and points in a knowledge snapshot (``fastlane.knowledge_snapshot``)."""
    facts, points = before
    by_name = dict(zip(_SNAPSHOT_NAMES, facts, strict=True))
    return Reads(tuple((name, by_name[name]) for name in sorted(names)),
                 tuple((n, points.get(n, MISSING)) for n in sorted(point_numbers, key=repr)))


_SNAPSHOT_NAMES: Final = tuple(f.name for f in dataclasses.fields(Knowledge) if f.name != "points")


class ReadsMemo:
    """Exchanges kept by what they read (module docstring); ``hits`` counts the exchanges it answered."""

    def __init__(self) -> None:
        self._commands: dict[bytes, list[Command]] = {}
        self._entries = 0
        self.hits = 0

    def command(self, data: bytes, k: Knowledge) -> Command | None:
        """The kept command of these bytes whose reads ``k`` holds, and the reads of one of its answers
        (else its answer cannot come from here, and the command would be judged again when it comes)."""
        for command in self._commands.get(data, ()):
            if command.reads.hold(k) and any(answer.reads.hold(k) for answers in command.answers.values()
                                             for answer in answers):
                return command
        return None

    def keep(self, command: bytes, host: FrameRecord, asked: Trace, answer: bytes, record: FrameRecord,
             answered: Trace, before: tuple[Any, ...], after: tuple[Any, ...]) -> None:
        """Keep a clean exchange the full path judged from the quiet state: the command (``asked``: its
        trace; it wrote nothing) and its answer (``answered``), the knowledge ``before`` and ``after``
        (snapshots). Traces that touched the knowledge as a whole are not kept."""
        if asked.wrote or answered.whole or host.window_s is None:
            return
        host_reads = _values(asked.reads, asked.point_reads, before)
        answer_reads = _values(answered.reads | asked.reads, answered.point_reads | asked.point_reads, before)
        facts, points = after
        by_name = dict(zip(_SNAPSHOT_NAMES, facts, strict=True))
        writes = Writes(tuple((name, by_name[name]) for name in sorted(answered.writes)),
                        tuple((n, points.get(n, MISSING)) for n in sorted(answered.point_writes, key=repr)))
        variants = self._commands.get(command)
        if variants is None:
            if self._entries >= ENTRIES:
                self._commands.clear()
                self._entries = 0
            variants = self._commands[command] = []
        kept = next((c for c in variants if _same(c.reads, host_reads) and c.window == host.window_s), None)
        if kept is None:
            if len(variants) >= VARIANTS:
                return
            kept = Command(host, host.window_s, host_reads)
            variants.append(kept)
            self._entries += 1
        answers = kept.answers.setdefault(answer, [])
        if len(answers) < VARIANTS and not any(_same(a.reads, answer_reads) for a in answers):
            answers.append(Answer(record, answer_reads, writes))
            self._entries += 1


def _same(a: Reads, b: Reads) -> bool:
    return a.facts == b.facts and a.points == b.points
