"""The fast path of ``codec.diagnose`` for well-formed frames, derived from the spec tables at import.

How this works: most traffic is clean, and a clean frame needs none of the lenient walk's bookkeeping.
For each frame kind of ``spec.FRAME_SPECS`` one regular expression is compiled from its layout: the
header, each field as exactly its width of upper-case hex or decimal digits whose value is inside the
field's range (``digits_in_range``; an alarm code only as one the vendor lists with a meaning), each
literal verbatim, then CR LF, nothing after. ``decode_clean(data, role)`` returns the frame when the bytes
match, and None otherwise: then the caller takes the full path, which lists every violation. A match
needs no further check, so a field's value is one ``int`` of its digits. A frame it returns is exactly
what ``diagnose`` returns with no violation (tests/test_fastcodec.py proves it with hypothesis); the
grammar itself stays defined once, in ``spec.py`` and ``grammar.py``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from typing import Final

from . import spec
from .frames import FRAME_CLASSES, Frame

_DIGITS: Final = {16: "0123456789ABCDEF", 10: "0123456789"}
_LISTED_ALARMS: Final = frozenset(c for c, meaning in spec.ALARMS.items() if meaning is not None)


def _one_of(digits: str) -> bytes:
    return re.escape(digits).encode("ascii") if len(digits) == 1 else b"[" + digits.encode("ascii") + b"]"


def digits_in_range(lo: int, hi: int, width: int, radix: int) -> bytes:
    """A pattern for exactly ``width`` upper-case digits of ``radix`` whose value is in ``[lo, hi]``."""
    if width == 0:
        return b""
    digits = _DIGITS[radix]
    if lo == 0 and hi == radix ** width - 1:  # any digits
        return _one_of(digits) + (b"{%d}" % width if width > 1 else b"")
    unit = radix ** (width - 1)
    (lo_d, lo_rest), (hi_d, hi_rest) = divmod(lo, unit), divmod(hi, unit)
    rest = width - 1
    any_rest = b"" if not rest else _one_of(digits) + (b"{%d}" % rest if rest > 1 else b"")
    if lo_d == hi_d:
        return _one_of(digits[lo_d]) + digits_in_range(lo_rest, hi_rest, width - 1, radix)
    if lo_rest == 0 and hi_rest == unit - 1:  # whole leading digits
        return _one_of(digits[lo_d:hi_d + 1]) + any_rest
    parts = [_one_of(digits[lo_d]) + digits_in_range(lo_rest, unit - 1, width - 1, radix)]
    if hi_d - lo_d > 1:
        parts.append(_one_of(digits[lo_d + 1:hi_d]) + any_rest)
    parts.append(_one_of(digits[hi_d]) + digits_in_range(0, hi_rest, width - 1, radix))
    return b"(?:" + b"|".join(parts) + b")"


def _field_pattern(fs: spec.FrameSpec, name: str) -> bytes:
    field = spec.FIELDS[name]
    if field.text:
        return b"([0-9]{%d})" % field.width
    if name == "code" and fs.header == spec.ALARM_HEADER:  # only a code the vendor lists with a meaning
        codes = sorted(c for c in _LISTED_ALARMS if fs.field_range(name)[0] <= c <= fs.field_range(name)[1])
        return b"(" + b"|".join(f"{c:0{field.width}X}".encode("ascii") for c in codes) + b")"
    lo, hi = fs.field_range(name)
    return b"(" + digits_in_range(lo, hi, field.width, field.radix) + b")"


def _pattern(fs: spec.FrameSpec) -> re.Pattern[bytes]:
    parts = [re.escape(fs.header.encode("ascii"))]
    for item in fs.layout:
        if isinstance(item, str):
            parts.append(_field_pattern(fs, item))
        else:
            parts.append(re.escape(item.text.encode("ascii")))
    parts.append(re.escape(spec.TERMINATOR))
    return re.compile(b"".join(parts))


# role -> header bytes -> (the pattern, the frame kind's constructor from its values in wire order, each
# field's radix, 0 for text, and whether any field is text)
_Make = Callable[[Iterable[object]], Frame]
_Entry = tuple[re.Pattern[bytes], _Make, tuple[int, ...], bool]
_TABLE: Final[dict[str, dict[bytes, _Entry]]] = {role: {} for role in spec.ROLES}
for _fs in spec.FRAME_SPECS:
    _radixes = tuple(0 if spec.FIELDS[name].text else spec.FIELDS[name].radix for name in _fs.field_names)
    _make: _Make = FRAME_CLASSES[_fs.key]._make  # type: ignore[attr-defined]  # the NamedTuple's own
    _TABLE[_fs.role][_fs.header.encode("ascii")] = (_pattern(_fs), _make, _radixes, 0 in _radixes)


def decode_clean(data: bytes, role: str) -> Frame | None:
    """The frame ``data`` holds if it is well formed and every field in range, else None (the caller,
    ``codec.read_frame``, remembers the last distinct lines). The pattern has checked every field, so the
    frame is made from its values unchecked (``Frame``)."""
    entry = _TABLE[role].get(data[: spec.HEADER_WIDTH])
    if entry is None:
        return None
    pattern, make, radixes, text = entry
    match = pattern.fullmatch(data)
    if match is None:
        return None
    if text:  # a text field (the version) is kept as its digits
        return make([digits.decode("ascii") if not radix else int(digits, radix)
                     for digits, radix in zip(match.groups(), radixes, strict=True)])
    return make(map(int, match.groups(), radixes))
