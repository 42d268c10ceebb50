"""The part of a view's line that a frame record's direction, bytes, header and frame decide, made once per
distinct frame and kept.

How this works: a view's line for a frame record is its numbers (record number, time, the command
answered, the latency) around a part that is a pure function of the record's direction, bytes, header
and frame (the JSON from ``"dir"`` to ``"sides"``; the text view's bytes and decoded frame). A
``FrameParts`` keeps, per direction and frame bytes, the last part made with the frame object it was made
from; ``get`` gives it again only for that very frame object (frames are immutable) with the same header:
nothing about earlier records is replayed, only a function of the frame is not computed twice. It pays
because the codec hands out one frame object per distinct bytes (``codec.read_frame`` remembers the last
lines it read) and traffic repeats its frames; on traffic that does not, each lookup misses and the part
is made as without it. At most ``KEPT`` parts a direction are kept.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Final, Generic, TypeVar

KEPT: Final = 4096  # parts kept a direction (then forgotten all at once, and made again as they come)

T = TypeVar("T")


class FrameParts(Generic[T]):
    """Parts made by ``make(direction, raw, header, frame)`` (a part None: that record has none, and it is
    not kept), kept per direction ``host`` or ``device`` and frame bytes."""

    __slots__ = ("_kept", "_make")

    def __init__(self, make: Callable[[Any, Any, Any, Any], T]) -> None:
        self._make = make
        # direction -> frame bytes -> (the frame and header the part was made from, the part)
        self._kept: dict[str, dict[bytes, tuple[Any, Any, T]]] = {"host": {}, "device": {}}

    def get(self, direction: Any, raw: Any, header: Any, frame: Any) -> T:
        """The part of a record with this direction, bytes, header and frame: the one kept when it was
        made from this very frame object and an equal header, else made now (``made``)."""
        try:
            known = self._kept[direction][raw]
        except (KeyError, TypeError):  # none kept (TypeError: a direction or bytes no dict could hold)
            return self.made(direction, raw, header, frame)
        if known[0] is frame and known[1] == header and type(raw) is bytes and type(direction) is str:
            return known[2]
        return self.made(direction, raw, header, frame)

    def made(self, direction: Any, raw: Any, header: Any, frame: Any) -> T:
        """The part made now, and kept (but None, or for a direction other than ``host`` and ``device`` or
        bytes of another type)."""
        part = self._make(direction, raw, header, frame)
        by_raw = self._kept.get(direction) if type(direction) is str else None
        if part is not None and by_raw is not None and type(raw) is bytes:
            if len(by_raw) >= KEPT:
                by_raw.clear()
            by_raw[raw] = (frame, header, part)
        return part
