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
