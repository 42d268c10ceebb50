"""Keep the device as it was: snapshot the 15 points, the OUT ports and the axis position first,
restore and verify last.

``take_snapshot`` runs before the suite writes anything; a point or the OUT ports that cannot be read
stop the run (nothing could be restored). ``restore`` writes back only what differs, then reads it again
to verify. A point the snapshot found never written (V or A ``0``, docs/protocol.md silent item 6) cannot be
written back (0WP takes V 1-9 and A 1-3), so on a real device the suite writes only points it can
restore plus those the user names (``Snapshot.scratch_order``); only the built-in simulator lends it
every point. The axis goes back to where it was when that was known (homed, inside the safe range) and
motion is allowed, at a gentle speed, verified by 0RC. The mode is left at 1 (communication): 0CM0 would
enable the external start inputs again, which only the operator may decide (``--xac1-restore-mode0``).
A device that does not answer during the restore leaves it unverified: the report then says so and
lists what the run sent that may have changed the device, with the values to check by hand.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from xac1_proto import spec
from xac1_proto.codec import diagnose
from xac1_proto.frames import (
    Frame,
    MoveDirect,
    MovePoint,
    ReadCurrent,
    ReadCurrentAnswer,
    ReadOutputs,
    ReadOutputsAnswer,
    ReadPoint,
    ReadPointAnswer,
    StoreCurrent,
    SwitchMode,
    WriteOutputs,
    WritePoint,
)
from xac1_proto.points import PointData

from .device import DeviceAbort, DeviceUnderTest, MotionRefused, PortLost, StoppedAnswering
from .evidence import Probe, describe_answer

POINTS = range(spec.FIELDS["n"].command_range[0], spec.FIELDS["n"].command_range[1] + 1)
# The way back to the starting position: a sixth of the top direct-move speed, the gentlest ramp.
RESTORE_VEL = spec.FIELDS["vel"].command_range[1] // 6
RESTORE_A = spec.FIELDS["a"].command_range[0]
MODE_NOTE = ("The controller is left in mode 1 (communication: external I/O disabled), as after any host "
             "session. The suite does not send 0CM0 on its own: that would enable the external I/O start "
             "inputs again without the operator's consent")


@dataclass
class Snapshot:
    points: dict[int, PointData]
    outputs: int
    position: int | None = None  # where the axis was, when homed (0RC Pos not FFFFFF)
    position_seen: str = "not read"  # what 0RC said at the start, for the report

    def scratch_order(self, named: Sequence[int] = (), anything: bool = False) -> list[int]:
        """Points the suite may write, in the order it uses them: those the user named, then those
        holding data (restorable); only when ``anything`` (the built-in simulator) every other point."""
        rest = sorted((n for n in self.points if n not in named),
                      key=lambda n: (not self.points[n].restorable, n))
        return list(named) + [n for n in rest if anything or self.points[n].restorable]

    @property
    def never_written(self) -> list[int]:
        return [n for n in sorted(self.points) if not self.points[n].restorable]


@dataclass
class RestoreReport:
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # changes the protocol cannot undo
    problems: list[str] = field(default_factory=list)  # a restore that failed
    unverified: list[str] = field(default_factory=list)  # no answer: not restored, not checked
    failed_items: list[str] = field(default_factory=list)  # what ``problems`` name ("point 3", ...)
    unverified_items: list[str] = field(default_factory=list)  # what ``unverified`` names

    @property
    def ok(self) -> bool:
        return not self.problems and not self.unverified


def _ask(dut: DeviceUnderTest, frame: Frame) -> Probe:
    """Send ``frame``; after silence, check the device is there (``StoppedAnswering`` if not) and ask
    once more; after an answer of another command or a damaged one (a late answer, a corrupted byte),
    let the line go quiet and ask once more. One lost or spoiled answer stops neither the snapshot nor
    the restore (every command sent here is read-only or writes back the same values)."""
    p = dut.send(frame)
    if p.silent:
        dut.settle()
        return dut.send(frame)
    if p.alarm is None and (p.frame is None or p.frame.header != frame.header or p.errors):
        dut.drain(min(dut.settings.timeout, 0.3))
        p = dut.send(frame)
    return p


def _late(dut: DeviceUnderTest, p: Probe) -> str:
    """A hint when an answer may have come late: none in time, partial, or bytes that arrived before a
    later command (a late answer)."""
    late = p.partial or p.exchange.stale or any(q.exchange.stale for q in dut.log[-6:])
    if late:
        return (f"; answers come later than {dut.settings.timeout:g} s: a slow device needs a longer wait, "
                f"e.g. {dut.settings.flag('timeout')} {2 * dut.settings.timeout:g}")
    if p.timed_out:
        return f"; if the device is slow to answer, try a longer wait: {dut.settings.flag('timeout')} S"
    return ""


def _read_point(dut: DeviceUnderTest, n: int) -> PointData:
    p = _ask(dut, ReadPoint(n=n))
    if not isinstance(p.frame, ReadPointAnswer):  # data that decodes is kept, even from a flawed answer
        raise DeviceAbort(f"cannot read point {n:X}: {describe_answer(p)} ({p.show()}){_late(dut, p)}")
    return PointData.of(p.frame)


def _read_outputs(dut: DeviceUnderTest) -> int:
    p = _ask(dut, ReadOutputs())
    if not isinstance(p.frame, ReadOutputsAnswer):
        raise DeviceAbort(f"cannot read the OUT ports: {describe_answer(p)} ({p.show()}){_late(dut, p)}")
    return p.frame.o


def take_snapshot(dut: DeviceUnderTest) -> Snapshot:
    """Read every point, the OUT ports and the position (an alarm found latched is reset first)."""
    dut.settle()
    snap = Snapshot({n: _read_point(dut, n) for n in POINTS}, _read_outputs(dut))
    p = _ask(dut, ReadCurrent())
    if isinstance(p.frame, ReadCurrentAnswer) and not p.errors:
        pos = p.frame.pos
        snap.position = None if pos == spec.UNKNOWN_POSITION else pos
        snap.position_seen = "FFFFFF (not homed)" if snap.position is None else f"0x{pos:06X}"
    else:
        snap.position_seen = describe_answer(p)
    return snap


def restore(dut: DeviceUnderTest, snap: Snapshot) -> RestoreReport:
    """Write back what changed and verify it by reading again; never raises for device trouble."""
    out = RestoreReport()
    try:
        dut.drain(min(dut.settings.timeout, 0.3))  # an interrupted probe's answer may still be coming
        # Whatever the bookkeeping says, the alarm state is unknown here: a signal may have landed between
        # a malformed command and the bookkeeping of its answer (an alarm latched, recorded as none).
        # settle() then sends 0%C first.
        dut.latched = None
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
            _ask(dut, WritePoint(n=n, v=before.v, a=before.a, o=before.o, pos=before.pos))
            after = _read_point(dut, n)
            if after == before:
                out.lines.append(f"point {n:X} restored to {before.show()}")
            else:
                out.problems.append(f"point {n:X}: wrote back {before.show()} but it reads {after.show()}")
                out.failed_items.append(f"point {n:X}")
        out.lines.append(f"{len(POINTS) - changed} of {len(POINTS)} points unchanged by the run")
        now_o = _read_outputs(dut)
        if now_o != snap.outputs:
            _ask(dut, WriteOutputs(o=snap.outputs))
            after_o = _read_outputs(dut)
            if after_o == snap.outputs:
                out.lines.append(f"OUT ports restored to {snap.outputs}")
            else:
                out.problems.append(f"OUT ports: wrote back {snap.outputs} but they read {after_o}")
                out.failed_items.append("the OUT ports")
        else:
            out.lines.append(f"OUT ports unchanged ({snap.outputs})")
        _restore_position(dut, snap, out)
        _mode(dut, out)
    except (StoppedAnswering, PortLost) as exc:
        out.unverified.append(f"the restore could not be done or verified: {exc}")
        changes = _changes_sent(dut, snap)
        out.unverified += [line for line, _ in changes]
        out.unverified_items += [item for _, item in changes if item]
    except DeviceAbort as exc:
        out.problems.append(f"restore stopped: {exc}")
        out.failed_items.append("the rest of the restore (stopped)")
    except Exception as exc:  # noqa: BLE001 - the report must say what happened, whatever it was
        out.problems.append(f"restore stopped: {type(exc).__name__}: {exc}")
        out.failed_items.append("the rest of the restore (stopped)")
    return out


def _changes_sent(dut: DeviceUnderTest, snap: Snapshot) -> list[tuple[str, str]]:
    """What the run sent that may have changed the device (answered or not), with the values it had at
    the start: what to check by hand when the restore could not be done; each line with what it names
    ("" when nothing)."""
    points: set[int] = set()
    outputs = moved = mode = False
    for p in dut.log:
        command, violations = diagnose(p.sent, spec.COMMAND)
        if violations:  # a malformed probe: refused with an alarm by a device that follows the rules
            continue
        if isinstance(command, (WritePoint, StoreCurrent)) and command.n in snap.points:
            points.add(command.n)
        outputs = outputs or isinstance(command, WriteOutputs)
        moved = moved or isinstance(command, (MovePoint, MoveDirect))
        mode = mode or isinstance(command, SwitchMode)
    out = [(f"not verified: point {n:X}, written during the run; it held {snap.points[n].show()} before",
            f"point {n:X}") for n in sorted(points)]
    if outputs:
        out.append((f"not verified: the OUT ports, written during the run; they were {snap.outputs} before",
                    "the OUT ports"))
    if moved:
        out.append((f"not verified: the axis position, moved during the run; 0RC read {snap.position_seen} "
                    f"before", "the axis position"))
    if mode:
        out.append(("not verified: the mode, switched during the run (0CM)", "the mode"))
    return out or [("the run sent nothing that changes the device (no write, no move)", "")]


def _position_now(dut: DeviceUnderTest) -> int | None:
    p = _ask(dut, ReadCurrent())
    return p.frame.pos if isinstance(p.frame, ReadCurrentAnswer) and not p.errors else None


def _restore_position(dut: DeviceUnderTest, snap: Snapshot, out: RestoreReport) -> None:
    """Move the axis back where it was, when that was known and may be done; say why not otherwise."""
    s, start = dut.settings, snap.position
    if not s.motion:
        out.lines.append(f"axis not moved by the run (motion not allowed); 0RC read {snap.position_seen} "
                         f"at the start")
        return
    now = _position_now(dut)
    if start is not None and now == start:
        out.lines.append(f"axis position unchanged: 0x{start:06X}, as at the start")
        return
    here = "unknown" if now is None or now == spec.UNKNOWN_POSITION else f"0x{now:06X}"
    why = None
    if start is None:
        why = f"it was not known at the start (0RC answered {snap.position_seen})"
    elif not s.in_range(start):
        why = f"the starting position 0x{start:06X} is outside the safe range {s.describe_range()}"
    if why is not None:
        out.warnings.append(f"axis position not restored: {why}; it is now {here}")
        return
    assert start is not None
    try:
        m = dut.send(MoveDirect(vel=RESTORE_VEL, a=RESTORE_A, pos=start))
    except MotionRefused as exc:
        out.warnings.append(f"axis position not restored (0x{start:06X} at the start, {here} now): {exc}")
        return
    after = _position_now(dut)
    if after == start:
        out.lines.append(f"axis moved back to its starting position 0x{start:06X} (from {here}; 0MV with "
                         f"vel {RESTORE_VEL:02X}, a sixth of the top speed, and A={RESTORE_A}, the slowest "
                         f"ramp) and 0RC confirms it")
    else:
        seen = "unknown" if after is None else f"0x{after:06X}"
        out.problems.append(f"axis position: moved back to 0x{start:06X} ({m.show()}) but 0RC reads {seen}")
        out.failed_items.append("the axis position")


def _mode(dut: DeviceUnderTest, out: RestoreReport) -> None:
    """Leave mode 1, or with ``restore_mode0`` send 0CM0 as the very last command."""
    if not dut.settings.restore_mode0:
        out.lines.append(f"{MODE_NOTE}; pass {dut.settings.flag('restore-mode0')} to have it sent last")
        return
    p = dut.send(SwitchMode(mode=0))
    if p.echoes():
        out.lines.append("mode set to 0 (external start) by 0CM0, the last command of the run, as asked "
                         f"({dut.settings.flag('restore-mode0')})")
    else:
        out.problems.append(f"0CM0 (to set mode 0 as asked) got {describe_answer(p)}")
        out.failed_items.append("mode 0")
