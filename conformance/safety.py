"""Keep the device as it was: snapshot the 15 points and the OUT ports first, restore and verify last.

``take_snapshot`` runs before the suite writes anything; a point or the OUT ports that cannot be read
stop the run (nothing could be restored). ``restore`` writes back only what differs, then reads it again
to verify. A point the snapshot found never written (V or A ``0``, PROTOCOL.md silent item 6) cannot be
written back (0WP takes V 1-9 and A 1-3), so the suite writes such points only when no restorable point
is left, and the report names each one it could not restore.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from xac1_proto import spec
from xac1_proto.frames import (
    ReadOutputs,
    ReadOutputsAnswer,
    ReadPoint,
    ReadPointAnswer,
    WriteOutputs,
    WritePoint,
)

from .dut import DeviceAbort, DeviceUnderTest
from .evidence import describe_answer

POINTS = range(spec.FIELDS["n"].command_range[0], spec.FIELDS["n"].command_range[1] + 1)


@dataclass(frozen=True)
class PointData:
    v: int
    a: int
    o: int
    pos: int

    @property
    def restorable(self) -> bool:
        """0WP can write these values back (its V and A ranges exclude the answers' 0)."""
        fs = WritePoint.spec()
        return all(fs.field_range(k)[0] <= getattr(self, k) <= fs.field_range(k)[1] for k in ("v", "a", "o"))

    def show(self) -> str:
        return f"V={self.v} A={self.a} O={self.o} Pos=0x{self.pos:06X}"


@dataclass
class Snapshot:
    points: dict[int, PointData]
    outputs: int

    def scratch_order(self) -> list[int]:
        """Points to write in tests: restorable ones first, then the rest."""
        return sorted(self.points, key=lambda n: (not self.points[n].restorable, n))


@dataclass
class RestoreReport:
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # changes the protocol cannot undo
    problems: list[str] = field(default_factory=list)  # a restore that failed

    @property
    def ok(self) -> bool:
        return not self.problems


def _read_point(dut: DeviceUnderTest, n: int) -> PointData:
    p = dut.send(ReadPoint(n=n))
    if not isinstance(p.frame, ReadPointAnswer):  # data that decodes is kept, even from a flawed answer
        raise DeviceAbort(f"cannot read point {n:X}: {describe_answer(p)} ({p.show()})")
    f = p.frame
    return PointData(f.v, f.a, f.o, f.pos)


def _read_outputs(dut: DeviceUnderTest) -> int:
    p = dut.send(ReadOutputs())
    if not isinstance(p.frame, ReadOutputsAnswer):
        raise DeviceAbort(f"cannot read the OUT ports: {describe_answer(p)} ({p.show()})")
    return p.frame.o


def take_snapshot(dut: DeviceUnderTest) -> Snapshot:
    """Read every point and the OUT ports (an alarm found latched is reset first)."""
    dut.settle()
    return Snapshot({n: _read_point(dut, n) for n in POINTS}, _read_outputs(dut))


def restore(dut: DeviceUnderTest, snap: Snapshot) -> RestoreReport:
    """Write back what changed and verify it by reading again; never raises for device trouble."""
    out = RestoreReport()
    try:
        dut.settle()
        changed = 0
        for n in POINTS:
            before, now = snap.points[n], _read_point(dut, n)
            if now == before:
                continue
            changed += 1
            if not before.restorable:
                out.warnings.append(f"point {n:X} was never written before the run ({before.show()}); the "
                                    f"run left {now.show()} and the protocol cannot erase a point")
                continue
            dut.send(WritePoint(n=n, v=before.v, a=before.a, o=before.o, pos=before.pos))
            after = _read_point(dut, n)
            if after == before:
                out.lines.append(f"point {n:X} restored to {before.show()}")
            else:
                out.problems.append(f"point {n:X}: wrote back {before.show()} but it reads {after.show()}")
        out.lines.append(f"{len(POINTS) - changed} of {len(POINTS)} points unchanged by the run")
        now_o = _read_outputs(dut)
        if now_o != snap.outputs:
            dut.send(WriteOutputs(o=snap.outputs))
            after_o = _read_outputs(dut)
            if after_o == snap.outputs:
                out.lines.append(f"OUT ports restored to {snap.outputs}")
            else:
                out.problems.append(f"OUT ports: wrote back {snap.outputs} but they read {after_o}")
        else:
            out.lines.append(f"OUT ports unchanged ({snap.outputs})")
    except DeviceAbort as exc:
        out.problems.append(f"restore stopped: {exc}")
    except Exception as exc:  # noqa: BLE001 - the report must say what happened, whatever it was
        out.problems.append(f"restore stopped: {type(exc).__name__}: {exc}")
    return out
