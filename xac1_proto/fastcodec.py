"""The fast path of ``codec.diagnose`` for well-formed frames, derived from the spec tables at import.

How this works: most traffic is clean, and a clean frame needs none of the lenient walk's bookkeeping.
For each frame kind of ``spec.FRAME_SPECS`` one regular expression is compiled from its layout (the
header, each field as exactly its width of upper-case hex or decimal digits, each literal verbatim, then
CR LF, nothing after). ``decode_clean(data, role)`` returns the frame when the bytes match and every
field is inside its range (an alarm code the vendor lists with a meaning, too), and None otherwise:
then the caller takes the full path, which lists every violation. A frame it returns is exactly what
``diagnose`` returns with no violation (tests/test_fastcodec.py proves it with hypothesis); the
grammar itself stays defined once, in ``spec.py`` and ``grammar.py``.
"""

from __future__ import annotations

import re
from typing import Final

from . import spec
from .frames import FRAME_CLASSES, Frame

_DIGITS: Final = {16: b"[0-9A-F]", 10: b"[0-9]"}

# a field's check: radix (0 for a text field, kept as its digits), lowest and highest value, and the
# values allowed (the alarm codes the vendor lists with a meaning; None: any in range)
Check = tuple[int, int, int, "frozenset[int] | None"]
_LISTED_ALARMS: Final = frozenset(c for c, meaning in spec.ALARMS.items() if meaning is not None)


def _check(fs: spec.FrameSpec, name: str) -> Check:
    field = spec.FIELDS[name]
    if field.text:
        return 0, 0, 0, None
    lo, hi = fs.field_range(name)
    listed = _LISTED_ALARMS if name == "code" and fs.header == spec.ALARM_HEADER else None
    return field.radix, lo, hi, listed


def _pattern(fs: spec.FrameSpec) -> re.Pattern[bytes]:
    parts = [re.escape(fs.header.encode("ascii"))]
    for item in fs.layout:
        if isinstance(item, str):
            field = spec.FIELDS[item]
            parts.append(b"(" + _DIGITS[field.radix] + b"{%d})" % field.width)
        else:
            parts.append(re.escape(item.text.encode("ascii")))
    parts.append(re.escape(spec.TERMINATOR))
    return re.compile(b"".join(parts))


_Entry = tuple[re.Pattern[bytes], type[Frame], tuple[str, ...], tuple[Check, ...]]
_TABLE: Final[dict[tuple[bytes, str], _Entry]] = {
    (fs.header.encode("ascii"), fs.role): (
        _pattern(fs), FRAME_CLASSES[fs.key], fs.field_names,
        tuple(_check(fs, name) for name in fs.field_names),
    )
    for fs in spec.FRAME_SPECS
}


def decode_clean(data: bytes, role: str) -> Frame | None:
    """The frame ``data`` holds if it is well formed and every field in range, else None (the caller,
    ``codec.read_frame``, remembers the last distinct lines)."""
    entry = _TABLE.get((data[: spec.HEADER_WIDTH], role))
    if entry is None:
        return None
    pattern, cls, names, checks = entry
    match = pattern.fullmatch(data)
    if match is None:
        return None
    values: dict[str, int | str] = {}
    for name, (radix, lo, hi, listed), text in zip(names, checks, match.groups(), strict=True):
        if not radix:
            values[name] = text.decode("ascii")
            continue
        value = int(text, radix)
        if value < lo or value > hi or (listed is not None and value not in listed):
            return None  # out of range: the full path says why
        values[name] = value
    return cls.unchecked(**values)
