"""Never a move: every byte sequence the fuzzer sends is read as the most lenient controller might read
it, and refused when a motion command's header (``0MP``, ``0MV``: ``spec.MOVE_HEADERS``) appears anywhere.

How this works: ``lenient`` maps each byte as a forgiving firmware could: the eighth bit dropped (a 7-bit
UART), lower case read as upper case (docs/protocol.md silent item 2), the letter ``O`` read as the digit
``0`` (the vendor PDF's artefact, "Framing"), and NUL bytes skipped (a receiver that ignores them). A
controller may resynchronise inside garbage, so the header is searched for anywhere in the bytes, not only
at a line's start; the search runs over the whole byte sequence of a case, so a line cut by CR or by a
missing LF cannot hide one. ``check`` raises ``MotionLine``; ``defuse`` changes the fewest bytes (the
``M`` of each header found becomes ``X``) so that a generated case passes. The shell calls ``check`` on
every case before a byte of it leaves.
"""

from __future__ import annotations

from typing import Final

from .. import spec

# The headers no fuzz line may carry, read leniently: "0MP", "0MV".
MOVE_HEADERS: Final = tuple(sorted(spec.MOVE_HEADERS))
_LEAD: Final = spec.LEAD.decode("ascii")
_LETTER_O: Final = spec.LETTER_O.decode("ascii")
_SKIPPED: Final = 0x00  # NUL: a receiver may drop it and join what surrounds it
_DEFUSED: Final = ord("X")  # what the M of a header found becomes


class MotionLine(ValueError):
    """A byte sequence that a lenient controller could read as a move; nothing of it was sent."""


def _read(byte: int) -> str:
    """One byte as a lenient controller reads it."""
    ch = chr(byte & 0x7F).upper()
    return _LEAD if ch == _LETTER_O else ch


def lenient(data: bytes) -> tuple[str, list[int]]:
    """``data`` read leniently, and for each character the offset of the byte it came from."""
    text, where = [], []
    for i, byte in enumerate(data):
        if byte & 0x7F == _SKIPPED:
            continue
        text.append(_read(byte))
        where.append(i)
    return "".join(text), where


def motion_at(data: bytes) -> tuple[int, str] | None:
    """(byte offset, header) of the first motion header a lenient controller could read, or None."""
    text, where = lenient(data)
    hits = [(text.find(h), h) for h in MOVE_HEADERS if h in text]
    if not hits:
        return None
    at, header = min(hits)
    return where[at], header


def check(data: bytes) -> None:
    """Raise ``MotionLine`` when ``data`` could be read as a move (see the module docstring)."""
    hit = motion_at(data)
    if hit is not None:
        at, header = hit
        raise MotionLine(f"refused: byte {at} starts {header!r} read leniently (lower case, letter O, "
                         f"eighth bit dropped, NUL skipped); a move is never sent by xac1 fuzz")


def defuse(data: bytes) -> bytes:
    """``data`` with the ``M`` of every leniently read motion header replaced by ``X``."""
    out = bytearray(data)
    while True:
        text, where = lenient(bytes(out))
        hits = [text.find(h) for h in MOVE_HEADERS if h in text]
        if not hits:
            return bytes(out)
        out[where[min(hits) + 1]] = _DEFUSED
