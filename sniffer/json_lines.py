"""Records as JSON lines (docs/output.md): the views' one formatter of a record's JSON line, each line
``json.dumps`` of the record's ``to_dict`` (what ``record.to_json()`` gives, through ``json``).

How this works: a frame record's line is its numbers (``i``, ``t``; on an answer ``reply_to`` and
``latency_ms``) around a middle, ``"dir"`` to ``"sides"``, that depends on its direction, bytes, header
and frame only (``middle``), made once per distinct frame (``sniffer.frame_parts``). A middle is made
from a format per frame class, built at import from the frame classes of ``spec.FRAME_SPECS`` (the
field names in ``to_dict``'s order, each field a JSON number); numbers as ``json.dumps`` of
``round(x, 6)`` gives them (``fixed``); a record's violations, sides, details and line errors, when it
has them, as JSON lists of strings (``_noted``). Anything else (a value of an unusual type, a text
field, junk, timeouts) is the record's ``to_dict`` through ``json`` itself.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator
from operator import attrgetter
from typing import Any, Final

from xac1_proto import spec
from xac1_proto.frames import FRAME_CLASSES

from .frame_parts import FrameParts
from .records import FrameRecord, JunkRecord, Record, TimeoutRecord, field_names, severities_of, sides_of

# ``json.dumps(x, separators=(",", ":"))``, the encoder made once (``Record.to_json``)
ENCODE: Final[Callable[[Any], str]] = json.JSONEncoder(separators=(",", ":")).encode
_RECORD_TYPES: Final = (FrameRecord, JunkRecord, TimeoutRecord)
_DIR_JSON: Final = {"host": '"host"', "device": '"device"'}
_T_MAX: Final = 4294967296.0  # times below 2**32 s (and from 1 ms) are formatted by ``fixed``
_MS_MAX: Final = 1e12  # latencies below 1e12 ms (and from 1 us) are formatted by ``fixed``


def _fields_format(cls: type) -> tuple[str, Callable[[Any], tuple[Any, ...]], tuple[type, ...]] | None:
    """A frame class's ``fields`` as a JSON object with ``%d`` for each value, the getter of the values
    and their types when the format holds (every one ``int``); None for a class with a text field."""
    names = field_names(cls)
    if any(spec.FIELDS[name].text for name in names):
        return None
    get: Callable[[Any], tuple[Any, ...]]
    if len(names) > 1:
        get = attrgetter(*names)
    elif names:
        one = attrgetter(names[0])
        get = lambda frame: (one(frame),)  # noqa: E731
    else:
        get = lambda frame: ()  # noqa: E731
    return "{" + ",".join(f'"{name}":%d' for name in names) + "}", get, (int,) * len(names)


# frame class -> its fields' format, getter and value types (``_fields_format``)
_FIELDS: Final = {cls: shape for cls in set(FRAME_CLASSES.values())
                  if (shape := _fields_format(cls)) is not None}


def fixed(x: float, digits: int) -> str:
    """``repr(round(x, digits))`` for a float ``x`` from 0.001 up to 2**32 (``digits`` 6) or 1e12 (3).
    ``f"{x:.{digits}f}"`` gives the digits ``round`` rounds to (one correctly rounded conversion: half to
    even on the float's exact value). ``repr`` gives the shortest digits that read back as that rounded
    float; those digits, bar trailing zeros, are they: with 3 decimals below 1e12 they are at most 15
    significant digits (which always read back unchanged); with 6 below 2**32 a float's step is under
    1e-6, so no other 6-decimal number reads back as the same float."""
    text = f"{x:.{digits}f}".rstrip("0")
    return text + "0" if text[-1] == "." else text


def json_number(x: Any) -> str:
    """``json.dumps`` of a number (or None, or whatever else ``to_dict`` holds there)."""
    if type(x) is float and x - x == 0.0:
        return float.__repr__(x)
    if type(x) is int:
        return int.__repr__(x)
    return ENCODE(x)


def json_t(t: Any) -> str:
    """``json.dumps(round(t, 6))``: ``to_dict``'s ``t``."""
    if type(t) is float and 0.001 <= t < _T_MAX:
        return fixed(t, 6)
    return "null" if t is None else json_number(round(t, 6))


def json_ms(seconds: Any) -> str:
    """``json.dumps(round(seconds * 1000.0, 3))`` (``to_dict``'s ``latency_ms``)."""
    if seconds is None:
        return "null"
    ms = seconds * 1000.0
    if type(ms) is float and 0.001 <= ms < _MS_MAX:
        return fixed(ms, 3)
    return json_number(round(ms, 3))


def json_line(record: Record) -> str:
    """A record's line through ``json``: its ``to_dict`` encoded, and a newline."""
    if type(record) in _RECORD_TYPES:
        return ENCODE(record.to_dict()) + "\n"
    return record.to_json() + "\n"


_CLEAN: Final = '"violations":[],"sides":[],"severities":[]'
_UNJUDGED: Final = -len(_CLEAN)  # a middle but its (clean) violations and sides


def middle(direction: Any, raw: Any, header: Any, frame: Any) -> str | None:
    """A clean frame record's JSON from ``"dir"`` to ``"sides"`` (its direction, bytes, header and
    frame); None when a value is not of the usual types (the line is then ``json``'s)."""
    shown_dir = _DIR_JSON.get(direction) if type(direction) is str else None
    if shown_dir is None or type(raw) is not bytes:
        return None
    if header is None:
        shown_header = "null"
    elif type(header) is str:
        shown_header = ENCODE(header)
    else:
        return None
    if frame is None:
        fields = "null"
    else:
        shape = _FIELDS.get(type(frame))
        if shape is None:
            return None
        fmt, get, types = shape
        values = get(frame)
        if tuple(map(type, values)) != types:
            return None
        fields = fmt % values
    return f'"dir":{shown_dir},"raw":"{raw.hex()}","header":{shown_header},"fields":{fields},{_CLEAN}'


def _noted(record: FrameRecord) -> tuple[str, str] | None:
    """A frame record's ``"violations"`` and ``"sides"``, and its optional ``"details"`` and
    ``"line_errors"`` (with their leading comma), as its JSON line has them; None when one of them is not
    a tuple of strings (the line is then ``json``'s)."""
    lists = (record.violations, sides_of(record), severities_of(record), record.details,
             record.line_errors)  # as ``to_dict``
    if not all(type(items) is tuple and all(type(x) is str for x in items) for items in lists):
        return None
    codes, sides, severities, details, line_errors = ("[" + ",".join(map(ENCODE, items)) + "]"
                                                      for items in lists)
    notes = (f',"details":{details}' if record.details else "") + \
        (f',"line_errors":{line_errors}' if record.line_errors else "")
    return f'"violations":{codes},"sides":{sides},"severities":{severities}', notes


class JsonLines:
    """Makes records' JSON lines (``lines``), keeping the middles of the last distinct frames."""

    __slots__ = ("_middles",)

    def __init__(self) -> None:
        self._middles: FrameParts[str | None] = FrameParts(middle)

    def line(self, record: Record) -> str:
        """The record's JSON object (docs/output.md) and a newline (``lines`` of one)."""
        return next(self.lines((record,)))

    def lines(self, records: Iterable[Record]) -> Iterator[str]:
        """Each record's JSON object and a newline. A frame record's is its numbers around its middle (made
        once per distinct frame); any other record's, or one whose values are not of the usual types, is
        its ``to_dict`` through ``json`` (``json_line``)."""
        get = self._middles.get
        for record in records:
            if type(record) is not FrameRecord:
                yield json_line(record)
                continue
            (i, t, direction, raw, header, frame, violations, details, reply_to, latency, _t_last,
             line_errors, sides, _window, _severities) = record
            shown = get(direction, raw, header, frame) if type(i) is int else None
            notes = ""
            if shown is not None and (violations or details or line_errors or sides):
                noted = _noted(record)
                if noted is None:
                    shown = None
                else:
                    judged, notes = noted
                    shown = shown[:_UNJUDGED] + judged
            if shown is None:
                yield json_line(record)
                continue
            if type(t) is float and 0.001 <= t < _T_MAX:  # json_t(t) without its call (the usual time)
                shown_t = f"{t:.6f}".rstrip("0")
                if shown_t[-1] == ".":
                    shown_t += "0"
            else:
                shown_t = json_t(t)
            if direction != "device":
                yield f'{{"type":"frame","i":{i},"t":{shown_t},{shown}{notes}}}\n'
                continue
            ms = latency * 1000.0 if type(latency) is float else None
            if ms is not None and 0.001 <= ms < _MS_MAX:  # json_ms(latency) without its call
                shown_ms = f"{ms:.3f}".rstrip("0")
                if shown_ms[-1] == ".":
                    shown_ms += "0"
            else:
                shown_ms = json_ms(latency)
            shown_reply = reply_to if type(reply_to) is int else json_number(reply_to)
            yield (f'{{"type":"frame","i":{i},"t":{shown_t},{shown},"reply_to":{shown_reply},'
                   f'"latency_ms":{shown_ms}{notes}}}\n')
