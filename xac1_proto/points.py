"""One entry of the position table: a point's V, A, O and Pos, as 0WP writes them and 0RP reads them.

docs/protocol.md "Frames" (0RP, 0WP, 0WC, 0MP) and "Where the vendor text is silent" item 6 (a point never
written reads V 0, A 0). The one class every part uses: the simulator's table, the rulebook's knowledge of
the device, the conformance snapshot and its restore.
"""

from __future__ import annotations

from dataclasses import dataclass

from .frames import PointAnswer, WritePoint


@dataclass(frozen=True, slots=True)
class PointData:
    """A point of the position table: V, A, O, Pos."""

    v: int
    a: int
    o: int
    pos: int

    @classmethod
    def of(cls, frame: WritePoint | PointAnswer) -> PointData:
        """The point a frame carries (0WP; the 0RP, 0WP, 0WC and 0MP answers)."""
        return cls(frame.v, frame.a, frame.o, frame.pos)

    @property
    def restorable(self) -> bool:
        """0WP can write these values back (its V and A ranges exclude the 0 of a point never written)."""
        fs = WritePoint.frame_spec()
        return all(fs.field_range(k)[0] <= getattr(self, k) <= fs.field_range(k)[1] for k in ("v", "a", "o"))

    def show(self) -> str:
        """``V=9 A=3 O=0 Pos=012345``: the values as the frames write them."""
        return f"V={self.v} A={self.a} O={self.o} Pos={self.pos:06X}"


__all__ = ["PointData"]
