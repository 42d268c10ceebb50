"""What every capture reader yields and the conversation analyzer takes: timestamped, directed bytes."""

from __future__ import annotations

from typing import Final, Literal

Direction = Literal["host", "device"]
HOST: Final = "host"  # bytes the host sent (commands)
DEVICE: Final = "device"  # bytes the controller sent (answers)


class Chunk:
    """Bytes seen on one line. ``t``: unix seconds of the chunk's first byte (None when the source has
    no time). ``error``: what the capture tool said was wrong with these bytes on the wire (a UART
    framing or parity error), else None.

    A value: equal to another chunk of the same fields, hashed by them; nothing changes a chunk once
    made (a reader makes a new one instead). A plain slotted class, because readers make one per packet
    and its constructor is the cheapest Python has (a frozen dataclass's sets each field through
    ``object.__setattr__``; a ``NamedTuple``'s builds a tuple through a generated ``__new__``)."""

    __slots__ = ("t", "dir", "data", "error")

    t: float | None
    dir: Direction
    data: bytes
    error: str | None

    def __init__(self, t: float | None, dir: Direction, data: bytes, error: str | None = None) -> None:
        self.t = t
        self.dir = dir
        self.data = data
        self.error = error

    def _fields(self) -> tuple[float | None, Direction, bytes, str | None]:
        return self.t, self.dir, self.data, self.error

    def __eq__(self, other: object) -> bool:
        if type(other) is not Chunk:
            return NotImplemented
        return self._fields() == other._fields()

    def __hash__(self) -> int:
        return hash(self._fields())

    def __repr__(self) -> str:
        return f"Chunk(t={self.t!r}, dir={self.dir!r}, data={self.data!r}, error={self.error!r})"
