"""Strict and lenient decoding of one frame, from one walk over the spec's layouts.

``diagnose`` is the lenient path (the sniffer's): it finds the header (tolerating a letter ``O`` and a
header in lower case, each with its violation), then
checks length and terminator, walks the layout (literals, then each field through its construct) and
lists every deviation as a ``Violation`` with its byte offset, decoding whatever it can. ``parse`` is
the strict path: the same walk, raising the first violation in docs/protocol.md "Framing" order (header,
length, terminator, the ``2``, fields). Alarm-code notices (``reserved-alarm``, ``unknown-alarm``) do
not make a frame invalid: decoders accept any alarm code.
"""

from __future__ import annotations

import functools
from typing import Final, NamedTuple

import construct as cs

from . import grammar, spec
from .errors import FrameError, Violation
from .fastcodec import decode_clean
from .frames import FRAME_CLASSES, Frame, range_text

_NAMES = {0x0D: "CR", 0x0A: "LF"}


def show_bytes(data: bytes) -> str:
    """Bytes as a person reads them in a message: 'RP', CR, LF, 0x00, end of frame."""
    if not data:
        return "end of frame"
    out, text = [], ""
    for b in data:
        if 0x20 <= b < 0x7F:
            text += chr(b)
            continue
        if text:
            out.append(repr(text))
            text = ""
        out.append(_NAMES.get(b, f"0x{b:02X}"))
    if text:
        out.append(repr(text))
    return " ".join(out)


def _check_role(role: str) -> spec.Role:
    if role not in spec.ROLES:
        raise ValueError(f"role must be 'command' or 'answer', got {role!r}")
    return role  # type: ignore[return-value]


def _find_spec(data: bytes, role: spec.Role, out: list[Violation]) -> spec.FrameSpec | None:
    """Recognise the header, noting a letter O; None (with a violation) when nothing matches."""
    head = data[: spec.HEADER_WIDTH]
    text = head.decode("ascii", "replace")
    fs = spec.SPECS.get((text, role))
    if fs is not None:
        return fs
    lead_o = head[:1] == spec.LETTER_O
    if lead_o:
        fs = spec.SPECS.get(("0" + text[1:], role))
        if fs is not None:
            out.append(_letter_o(fs, role))
            return fs
    upper = text.upper()
    fs = spec.SPECS.get((("0" + upper[1:]) if lead_o else upper, role))
    if fs is not None and head.isascii():  # docs/protocol.md "Framing": 0rv is read as 0RV, a notice
        if lead_o:
            out.append(_letter_o(fs, role))
        at = next(i for i, (a, b) in enumerate(zip(text, fs.header, strict=False)) if a != b and i > 0)
        out.append(Violation("lowercase-hex", at, f"{fs.header} {role}: byte {at}: expected the header "
                             f"{fs.header} in upper case, got {show_bytes(head)} (lowercase-hex)"))
        return fs
    known = sorted(spec.HEADERS[role])
    matched = max((_common_prefix(head, h.encode()) for h in known), default=0)
    hint = ""
    if (text.upper(), role) in spec.SPECS or ("0" + text[1:].upper(), role) in spec.SPECS:
        hint = "; headers are upper case"
    elif role == spec.COMMAND and (text, spec.ANSWER) in spec.SPECS:
        hint = f"; {text} is an answer, not a command"
    out.append(Violation("unknown-command", matched,
                         f"{role}: byte {matched}: expected a header ({', '.join(known)}), "
                         f"got {show_bytes(head)}{hint} (unknown-command)"))
    return None


def _letter_o(fs: spec.FrameSpec, role: str) -> Violation:
    return Violation("letter-o", 0, f"{fs.header} {role}: byte 0: expected '0' (the digit zero), got 'O' "
                     f"(the letter O) (letter-o)", "letter-o" if role == spec.COMMAND else "letter-o-answer")


def _common_prefix(a: bytes, b: bytes) -> int:
    n = 0
    while n < min(len(a), len(b)) and a[n] == b[n]:
        n += 1
    return n


def _split_terminator(data: bytes, fs: spec.FrameSpec, out: list[Violation]) -> bytes:
    """The frame's body (without its terminator), noting a terminator that is not CR LF."""
    where = f"{fs.header} {fs.role}"
    if data.endswith(spec.TERMINATOR):
        return data[:-2]
    if data.endswith(b"\n"):
        if len(data) == fs.length and len(data) >= 2:
            at = len(data) - 2
            out.append(Violation("bad-terminator", at, f"{where}: byte {at}: expected CR LF, got "
                                 f"{show_bytes(data[at:])} (bad-terminator)"))
            return data[:-2]
        at = len(data) - 1
        out.append(Violation("bad-terminator", at, f"{where}: byte {at}: expected CR LF, got a bare "
                             f"LF (bad-terminator)"))
        return data[:-1]
    at = len(data)
    out.append(Violation("bad-terminator", at, f"{where}: byte {at}: expected CR LF, got "
                         f"end of data (bad-terminator)"))
    return data


def _decode_field(name: str, raw: bytes, at: int, fs: spec.FrameSpec,
                  out: list[Violation]) -> int | str | None:
    """One field through its construct, with case and range checks; None if it cannot be read."""
    field = spec.FIELDS[name]
    lo, hi = fs.field_range(name)
    where = f"{fs.header} {fs.role}: byte {at}: {field.label}"
    want = f"{field.width} {'hex' if field.radix == 16 else 'decimal'} digit" + \
        ("s" if field.width > 1 else "")
    if len(raw) < field.width:
        if any(v.code == "bad-length" for v in out):
            return None  # already said: the frame is short
        out.append(Violation("bad-length", at, f"{where}: expected {want}, got "
                             f"{show_bytes(raw)} (bad-length)"))
        return None
    try:
        value = grammar.FIELD_CONSTRUCTS[name].parse(raw)
    except (cs.ConstructError, UnicodeDecodeError):
        if field.text and raw.isascii() and raw.decode().isprintable():  # ver is only shown as 3 digits
            out.append(Violation("field-range", at, f"{where}: expected {want}, got {show_bytes(raw)} "
                                 f"(field-range)", "version-digits"))
            return raw.decode()
        out.append(Violation("field-range", at, f"{where}: expected {want} "
                             f"{'' if field.text else range_text(field, lo, hi)}, got "
                             f"{show_bytes(raw)} (field-range)".replace("  ", " ")))
        return None
    if field.radix == 16 and raw != raw.upper():
        out.append(Violation("lowercase-hex", at, f"{where}: expected upper-case hex, got "
                             f"{show_bytes(raw)} (lowercase-hex)"))
    if not field.text and not lo <= value <= hi:
        out.append(Violation("field-range", at, f"{where}: expected {range_text(field, lo, hi)}, "
                             f"got {show_bytes(raw)} (field-range)", _RANGE_READINGS.get((fs.header, name,
                                                                                          value), "")))
    if name == "code" and fs.header == spec.ALARM_HEADER:
        if value in spec.RESERVED_ALARMS:
            out.append(Violation("reserved-alarm", at, f"{where}: alarm {raw.decode()} has no "
                                 f"meaning in the vendor text (reserved-alarm)"))
        elif value not in spec.ALARMS:
            out.append(Violation("unknown-alarm", at, f"{where}: alarm {raw.decode()} is not in "
                                 f"the vendor's list (unknown-alarm)"))
    return value


# out-of-range values whose range is our reading, not the text's: 0WC N 0 (silent item 4)
_RANGE_READINGS: Final[dict[tuple[str, str, object], str]] = {("0WC", "n", 0): "0wc-point-0"}


def _walk(body: bytes, fs: spec.FrameSpec, out: list[Violation]) -> dict[str, int | str] | None:
    """Walk the layout over the body; the decoded fields, or None if a field could not be read."""
    values: dict[str, int | str] = {}
    at = spec.HEADER_WIDTH
    short = (fs.length - len(spec.TERMINATOR)) - len(body)  # bytes missing from the body
    ok = True
    for item in fs.layout:
        if isinstance(item, spec.Literal):
            seen = body[at: at + item.width]
            if seen != item.text.encode():
                out.append(Violation(item.code, at, f"{fs.header} {fs.role}: byte {at}: expected "
                                     f"{item.text!r}, got {show_bytes(seen)} ({item.code})"))
                if short >= item.width:  # omitted rather than replaced: the next field starts here
                    short -= item.width
                    continue
            at += item.width
            continue
        width = spec.FIELDS[item].width
        value = _decode_field(item, body[at: at + width], at, fs, out)
        if value is None:
            ok = False
        else:
            values[item] = value
        at += width
    return values if ok else None


def diagnose(data: bytes, role: str) -> tuple[Frame | None, list[Violation]]:
    """Decode ``data`` as far as possible and list every deviation; never raises on bad data."""
    reading = read_frame(bytes(data), role)
    return reading.frame, list(reading.violations)


class Reading(NamedTuple):
    """What the lenient decoder makes of one frame-shaped line: the frame (None when a field could not be
    read), every deviation, the header it was read as (None when unknown) and whether any deviation breaks
    a rule (``error``: not a notice; no frame is one)."""

    frame: Frame | None
    violations: tuple[Violation, ...]
    header: str | None
    error: bool


_reading: Final = Reading._make  # the NamedTuple's own constructor from a tuple (no keyword handling)
_ROLES: Final = frozenset(spec.ROLES)
READ_CACHE: Final = 4096  # distinct (bytes, role) remembered: about 2 MiB at most


@functools.lru_cache(maxsize=READ_CACHE)
def read_frame(data: bytes, role: str) -> Reading:
    """``diagnose`` with the header and the verdict on errors, of ``data`` as ``bytes``: a pure function
    of the bytes, so the last ``READ_CACHE`` distinct lines are remembered (traffic repeats its commands
    and most answers)."""
    clean = decode_clean(data, role) if role in _ROLES else None  # most traffic: a well-formed frame
    if clean is not None:
        return _reading((clean, (), clean.HEADER, False))
    checked = _check_role(role)
    frame, found = _diagnose_faulty(data, checked)
    header = frame.header if frame is not None else header_of(data, checked)
    error = frame is None or any(v.is_error for v in found)
    return Reading(frame, found, header, error)


def header_of(raw: bytes, role: spec.Role) -> str | None:
    """The spec header a frame is read as (a letter O read as the digit, lower case as upper), or None."""
    head = raw[: spec.HEADER_WIDTH].decode("ascii", "replace").upper()
    if head[:1] == "O":
        head = "0" + head[1:]
    return head if (head, role) in spec.SPECS else None


def _diagnose_faulty(data: bytes, role: spec.Role) -> tuple[Frame | None, tuple[Violation, ...]]:
    """``diagnose`` of bytes that are not a clean frame (frames and violations are immutable)."""
    out: list[Violation] = []
    fs = _find_spec(data, role, out)
    if fs is None:
        return None, tuple(out)
    if len(data) != fs.length:
        at = min(len(data), fs.length)
        out.append(Violation("bad-length", at, f"{fs.header} {role}: byte {at}: expected "
                             f"{fs.length} bytes, got {len(data)} (bad-length)"))
    body = _split_terminator(data, fs, out)
    values = _walk(body, fs, out)
    out.sort(key=lambda v: (spec.CHECK_ORDER.get(v.code, 9), v.offset or 0))
    if values is None:
        return None, tuple(out)
    return FRAME_CLASSES[fs.key].unchecked(**values), tuple(out)


def parse(data: bytes, role: str) -> Frame:
    """Decode one whole frame (CR LF included) strictly; raise ``FrameError`` on the first
    violation in docs/protocol.md "Framing" order."""
    frame, violations = diagnose(data, role)
    for v in violations:
        if v.code not in ("reserved-alarm", "unknown-alarm"):
            raise FrameError.from_violation(v, bytes(data))
    assert frame is not None  # no violation means every field decoded
    return frame
