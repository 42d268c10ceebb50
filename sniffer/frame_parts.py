"""The part of a view's line that a frame record's direction, bytes, header and frame decide, made once per
distinct frame and kept.

How this works: a view's line for a clean frame record is its numbers (record number, time, the command
answered, the latency) around a part that is a pure function of the record's direction, bytes, header
and frame (the JSON from ``"dir"`` to ``"sides"``; the text view's bytes and decoded frame). A
``FrameParts`` keeps, per direction and frame bytes, the last part made with the frame object it was made
from; a record gets it again only when it holds that very frame object (frames are immutable) with the
same header: nothing about earlier records is replayed, only a function of the frame is not computed
twice. It pays because the codec hands out one frame object per distinct bytes (``codec.read_frame``
remembers the last lines it read) and traffic repeats its frames; on traffic that does not, each lookup
misses and the part is made as without it. At most ``KEPT`` parts a direction are kept.

A view looks a part up in its loop (``kept[direction].get(raw)``, the frame and header checked) and
calls ``made`` on a miss.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Final

KEPT: Final = 4096  # parts kept a direction (then forgotten all at once, and made again as they come)

# frame bytes -> (the frame and header the part was made from, the part)
Kept = dict[bytes, tuple[Any, Any, str]]


class FrameParts:
    """Parts made by ``make(direction, raw, header, frame)`` (None: that record has no such part), kept
    per direction (``kept``: ``{"host": {raw: (frame, header, part)}, "device": {...}}``)."""

    __slots__ = ("kept", "_make")

    def __init__(self, make: Callable[[str, bytes, Any, Any], str | None]) -> None:
        self._make = make
        self.kept: dict[str, Kept] = {"host": {}, "device": {}}

    def made(self, direction: Any, raw: bytes, header: Any, frame: Any) -> str | None:
        """The part made (and kept, for a direction ``host`` or ``device``)."""
        part = self._make(direction, raw, header, frame)
        by_raw = self.kept.get(direction)
        if part is not None and by_raw is not None:
            if len(by_raw) >= KEPT:
                by_raw.clear()
            by_raw[raw] = (frame, header, part)
        return part
