"""What every capture reader yields and the conversation analyzer takes: timestamped, directed bytes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, Literal

Direction = Literal["host", "device"]
HOST: Final = "host"  # bytes the host sent (commands)
DEVICE: Final = "device"  # bytes the controller sent (answers)


@dataclass(frozen=True, slots=True)
class Chunk:
    """Bytes seen on one line. ``t``: unix seconds of the chunk's first byte (None when the source has
    no time). ``error``: what the capture tool said was wrong with these bytes on the wire (a UART
    framing or parity error), else None."""

    t: float | None
    dir: Direction
    data: bytes
    error: str | None = None


class _Blank:
    """Chunk's slots with no frozen ``__setattr__``: a chunk is filled in as one of these, then becomes a
    ``Chunk`` (``__class__`` may change between classes of the same slots)."""

    __slots__ = Chunk.__slots__
    t: float | None
    dir: Direction
    data: bytes
    error: str | None


def new_chunk(t: float | None, dir: Direction, data: bytes, error: str | None = None) -> Chunk:
    """``Chunk(t, dir, data, error)`` built three times faster, for readers' hot loops: the frozen
    dataclass's ``__init__`` sets each field through ``object.__setattr__``."""
    c = _Blank()
    c.t = t
    c.dir = dir
    c.data = data
    c.error = error
    c.__class__ = Chunk  # type: ignore[assignment]
    return c  # type: ignore[return-value]
