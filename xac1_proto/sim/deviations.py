"""Byte-level deviations: how an answer's wire bytes are spoiled when a deviation is on.

The model builds every answer with the frame classes' ``to_bytes()``; the deviations in ``DEVIATIONS``
that change the *shape* of an answer (``no-2``, ``wrong-length``, ``lf-only``, ``letter-o``,
``swapped-fields``, ``wrong-reset-answer``) are applied here, afterwards, using the spec's layouts to
find the bytes. Deviations of *behaviour* (not latched, not stored, ...) live in the model.
"""

from __future__ import annotations

from typing import Final

from .. import spec
from ..frames import Frame

# "swapped-fields" spoils the answers that carry a point's V and A and are no echo (0RP, 0RC, 0WC, 0MP)
_SWAPPED: Final = frozenset(fs.header for fs in spec.FRAME_SPECS
                            if fs.role == spec.ANSWER and not fs.echo and {"v", "a"} <= set(fs.field_names))


def spoil(frame: Frame, raw: bytes, deviations: frozenset[str]) -> bytes:
    """``raw`` (the frame's correct bytes) with the shape deviations applied."""
    if not deviations:
        return raw
    fs = frame.frame_spec()
    data = bytearray(raw)
    if "swapped-fields" in deviations and frame.header in _SWAPPED and "v" in fs.offsets():
        v, a = fs.offsets()["v"], fs.offsets()["a"]
        data[v], data[a] = data[a], data[v]
    if "wrong-reset-answer" in deviations and frame.header == spec.RESET_HEADER:
        at = fs.literal_offset(spec.RESET_OK)
        if at is not None:
            data[at: at + spec.RESET_OK.width] = b"01"
    if "no-2" in deviations:
        at = fs.literal_offset(spec.TWO)
        if at is not None:
            del data[at: at + spec.TWO.width]
    if "wrong-length" in deviations:
        data[-len(spec.TERMINATOR): -len(spec.TERMINATOR)] = b" "
    if "lf-only" in deviations and data.endswith(spec.TERMINATOR):
        del data[-2]
    if "letter-o" in deviations and data[:1] == spec.LEAD:
        data[0:1] = spec.LETTER_O
    return bytes(data)
