"""The construct grammar: one struct per frame kind, built from the tables in ``spec.py``.

Each struct covers a whole frame, header to CR LF, and ends with ``Terminated`` so that trailing bytes
are never ignored. Fields are small adapters over ``Bytes``: upper-case hex or decimal digits of a fixed
width. ``parse``/``diagnose`` in ``codec.py`` check a frame's shape first (header, length, terminator,
literals: docs/protocol.md "Framing") and decode each field with the same field constructs; ``Frame.to_bytes``
builds with the whole-frame struct. Nothing else in the package knows a frame's layout.
"""

from __future__ import annotations

from typing import Any, Final

import construct as cs

from . import spec


class Digits(cs.Adapter):
    """A fixed-width number written in upper-case hex or decimal digits (``text``: kept as a str)."""

    def __init__(self, field: spec.FieldSpec):
        super().__init__(cs.Bytes(field.width))
        self.field = field

    def _decode(self, obj: bytes, context: Any, path: str) -> int | str:
        text = obj.decode("ascii")  # raises UnicodeDecodeError on non-ASCII: caller reports it
        digits = "0123456789ABCDEFabcdef" if self.field.radix == 16 else "0123456789"
        if not text or any(c not in digits for c in text):
            raise cs.ValidationError(f"not {'hex' if self.field.radix == 16 else 'decimal'} digits")
        return text if self.field.text else int(text, self.field.radix)

    def _encode(self, obj: int | str, context: Any, path: str) -> bytes:
        if self.field.text:
            return str(obj).encode("ascii")
        return self.field.show(int(obj)).encode("ascii")


FIELD_CONSTRUCTS: Final[dict[str, Digits]] = {name: Digits(f) for name, f in spec.FIELDS.items()}


def _item(item: spec.Item) -> cs.Construct:
    if isinstance(item, str):
        return item / FIELD_CONSTRUCTS[item]
    return cs.Const(item.text.encode("ascii"))


def frame_struct(fs: spec.FrameSpec) -> cs.Struct:
    """The whole-frame struct of one frame kind: header, layout, CR LF, end of data."""
    return cs.Struct(
        cs.Const(fs.header.encode("ascii")),
        *(_item(i) for i in fs.layout),
        cs.Const(spec.TERMINATOR),
        cs.Terminated,
    )


STRUCTS: Final[dict[tuple[str, spec.Role], cs.Struct]] = {
    fs.key: frame_struct(fs) for fs in spec.FRAME_SPECS
}
