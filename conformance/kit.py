"""What the checks send: scratch points, safe values, one sample exchange per command kind, and the
catalogue of malformed commands.

Everything is built from frames (the grammar) or by spoiling a frame's bytes at an offset the spec
gives, so no frame length or header is written here by hand. Values are chosen so that a broken rule
shows: V and A differ (a device that swaps them is caught), Pos carries hex letters where the safe
range allows, and a write never targets a position outside the safe range.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from xac1_proto import spec
from xac1_proto.dut.device import DeviceUnderTest, MotionRefused
from xac1_proto.dut.evidence import Probe, describe_answer, expect
from xac1_proto.dut.safety import Snapshot
from xac1_proto.frames import (
    AlarmAnswer,
    AlarmReset,
    AlarmResetAnswer,
    Frame,
    MoveDirect,
    MovePoint,
    ReadCurrent,
    ReadOutputs,
    ReadPoint,
    ReadVersion,
    StoreCurrent,
    SwitchMode,
    WriteOutputs,
    WritePoint,
)

COMMAND_HEADERS = sorted(h for (h, role) in spec.SPECS if role == spec.COMMAND)
MOTION_HEADERS = sorted(spec.MOVE_HEADERS)
TWO_ANSWERS = sorted(h for (h, role), fs in spec.SPECS.items()
                     if role == spec.ANSWER and spec.TWO in fs.layout and h != spec.ALARM_HEADER)
FAST_VEL = spec.FIELDS["vel"].command_range[1]
FAST_V = spec.FIELDS["v"].command_range[1]
HIGH_A = spec.FIELDS["a"].command_range[1]


def reset_ok(p: Probe) -> bool:
    """The answer is the reset answer with its ``00`` (framing flaws aside)."""
    return isinstance(p.frame, AlarmResetAnswer) and not any(v.code == "field-range" for v in p.violations)


def two_offset(header: str) -> int:
    """Byte offset of the mandatory ``2`` in ``header``'s answer."""
    at = spec.SPECS[(header, spec.ANSWER)].literal_offset(spec.TWO)
    if at is None:
        raise ValueError(f"{header} answers carry no 2")
    return at


class NotEnoughPoints(Exception):
    """A check needs more points the suite may write than this run has; the message says what to pass."""


class Kit:
    """Shared per run: which points to write, safe positions, and sample exchanges per command kind."""

    def __init__(self, dut: DeviceUnderTest, snapshot: Snapshot) -> None:
        self.dut = dut
        self.snapshot = snapshot
        s = dut.settings
        self.scratch = snapshot.scratch_order(s.scratch_points, anything=s.simulator)
        self.samples: dict[str, Probe] = {}

    def point(self, k: int = 0) -> int:
        """The k-th distinct point the suite may write: those named with --xac1-scratch-points, then those
        that held data (restored at the end); on the built-in simulator any point. ``NotEnoughPoints``
        when the run has fewer than k + 1."""
        if k >= len(self.scratch):
            raise NotEnoughPoints(self._shortage(k + 1))
        return self.scratch[k]

    def _shortage(self, need: int) -> str:
        have = self.scratch
        flag = self.dut.settings.flag("scratch-points")
        named = set(self.dut.settings.scratch_points)
        spare = [n for n in self.snapshot.never_written if n not in named]
        offer = sorted(named | set(spare[: need - len(have)]))
        listed = ", ".join(f"{n:X}" for n in have) or "none"
        why = ("named with " + flag + (" or " if len(have) > len(named) else "")) if named else ""
        why += "held data, written back at the end" if len(have) > len(named) or not named else ""
        return (f"needs {need} points the suite may overwrite, this run has {len(have)} ({listed}: {why}). "
                f"The {len(spare)} never-written points are left alone: the protocol cannot make a point "
                f"never-written again. To run this check, let the suite overwrite some: "
                f"{flag} {','.join(f'{n:X}' for n in offer)}")

    def safe_pos(self, k: int = 0) -> int:
        """A position to store or move to: inside the safe range, or (no motion) a Pos a point held."""
        if self.dut.settings.safe_range is None:
            n = self.scratch[k % len(self.scratch)] if self.scratch else self.point(0)
            return self.snapshot.points[n].pos
        targets = self.dut.safe_targets(4)
        return targets[k % len(targets)]

    def other_target(self) -> int:
        """A safe target different from where the axis is now (so a move that is not done shows)."""
        here = self.dut.position
        return next((t for t in self.dut.safe_targets(4) if t != here), self.safe_pos(0))

    def write_safe_point(self, k: int = 0, v: int = FAST_V, a: int = HIGH_A, o: int | None = None) -> Probe:
        """Store a safe target in scratch point k (fast V, high A unless told) and expect the echo."""
        o = self.snapshot.outputs if o is None else o
        p = self.dut.send(WritePoint(n=self.point(k), v=v, a=a, o=o, pos=self.safe_pos(k)))
        expect(p.answered, f"0WP (needed to prepare the check) got {describe_answer(p)}", p)
        return p

    def require_homed(self) -> None:
        """Home the axis if it is not (MotionRefused when homing is not allowed)."""
        if not self.dut.settings.motion:
            raise MotionRefused("the axis must be homed first and motion is not allowed")
        self.dut.home_if_needed()

    # ---- one harmless, valid command per kind ----

    def command(self, header: str) -> Frame:
        """A valid command of this kind that changes nothing the restore cannot undo."""
        n = self.point(0)
        makers: dict[str, Callable[[], Frame]] = {
            ReadPoint.HEADER: lambda: ReadPoint(n=n),
            WritePoint.HEADER: lambda: WritePoint(n=n, v=7, a=2, o=1, pos=self.safe_pos(0)),
            ReadCurrent.HEADER: ReadCurrent,
            StoreCurrent.HEADER: lambda: StoreCurrent(n=n),
            MovePoint.HEADER: lambda: MovePoint(n=n),
            MoveDirect.HEADER: lambda: MoveDirect(vel=FAST_VEL, a=HIGH_A, pos=self.other_target()),
            ReadOutputs.HEADER: ReadOutputs,
            WriteOutputs.HEADER: lambda: WriteOutputs(o=self.snapshot.outputs),
            ReadVersion.HEADER: ReadVersion,
            SwitchMode.HEADER: lambda: SwitchMode(mode=1),
            AlarmReset.HEADER: AlarmReset,
        }
        return makers[header]()

    def prepare(self, header: str) -> None:
        """Bring the device where ``header``'s command gets its normal answer (homed for 0WC, a safe
        point for 0MP); MotionRefused when that would need motion the run does not allow."""
        if header in spec.MOVE_HEADERS or header == StoreCurrent.HEADER:
            self.require_homed()
        if header == MovePoint.HEADER:
            self.write_safe_point(0)

    def sample(self, header: str) -> Probe:
        """One exchange of this command kind, sent once per run and cited by every check that uses it."""
        if header not in self.samples:
            self.prepare(header)
            self.samples[header] = self.dut.send(self.command(header))
        p = self.samples[header]
        self.dut.cite(p)
        return p


@dataclass(frozen=True)
class Malformed:
    """A command broken in one way; ``make(kit)`` builds its bytes (always ending in LF)."""

    name: str
    what: str
    make: Callable[[Kit], bytes]
    moves: bool = False


def _swap(raw: bytes, at: int, new: bytes) -> bytes:
    return raw[:at] + new + raw[at + len(new):]


def _two_at(frame: Frame) -> int:
    at = frame.frame_spec().literal_offset(spec.TWO)
    if at is None:
        raise ValueError(f"{frame.header} has no 2")
    return at


def _field_at(frame_cls: type[Frame], name: str) -> int:
    return frame_cls.frame_spec().offsets()[name]


def _wp(kit: Kit, **over: int) -> Frame:
    values = dict(n=kit.point(0), v=7, a=2, o=1, pos=kit.safe_pos(0)) | over
    return WritePoint.unchecked(**values)


END = spec.TERMINATOR
MALFORMED: tuple[Malformed, ...] = (
    Malformed("too-long", "0RP with one byte too many",
              lambda k: ReadPoint(n=k.point(0)).to_bytes()[:-len(END)] + b"1" + END),
    Malformed("too-short", "0WP with one Pos digit missing",
              lambda k: _wp(k).to_bytes()[:-len(END) - 1] + END),
    Malformed("lf-only", "0RV ended by LF alone",
              lambda k: ReadVersion().to_bytes()[:-len(END)] + END[-1:]),
    Malformed("bad-terminator", "0RS of the right length whose CR is a space",
              lambda k: ReadOutputs().to_bytes()[:-len(END)] + b" " + END[-1:]),
    Malformed("letter-o", "0RV starting with the letter O",
              lambda k: spec.LETTER_O + ReadVersion().to_bytes()[1:]),
    Malformed("unknown-header", "a header no command has (0XY)", lambda k: b"0XY" + END),
    Malformed("answer-header", "the alarm answer's header sent as a command (0%%01)",
              lambda k: AlarmAnswer(code=spec.ALARM_COMM).to_bytes()),
    Malformed("n-out-of-range", "0RP with N = 0 (0RP takes 1-F)",
              lambda k: ReadPoint.unchecked(n=0).to_bytes()),
    Malformed("v-out-of-range", "0WP with V = 0 (commands take 1-9)", lambda k: _wp(k, v=0).to_bytes()),
    Malformed("a-out-of-range", "0WP with A = 4 (1-3)", lambda k: _wp(k, a=4).to_bytes()),
    Malformed("o-out-of-range", "0WS with O = 4 (0-3)", lambda k: WriteOutputs.unchecked(o=4).to_bytes()),
    Malformed("mode-out-of-range", "0CM with m = 2 (0-1)", lambda k: SwitchMode.unchecked(mode=2).to_bytes()),
    Malformed("vel-out-of-range", "0MV with vel = 00 (01-3C)",
              lambda k: MoveDirect.unchecked(vel=0, a=HIGH_A, pos=k.other_target()).to_bytes(), moves=True),
    Malformed("missing-2-0WS", "0WS whose 2 is a 0",
              lambda k: _swap(WriteOutputs(o=1).to_bytes(), _two_at(WriteOutputs(o=1)), b"0")),
    Malformed("missing-2-0WP", "0WP whose 2 is a 3",
              lambda k: _swap(_wp(k).to_bytes(), _two_at(_wp(k)), b"3")),
    Malformed("non-hex-pos", "0WP with a G in Pos",
              lambda k: _swap(_wp(k).to_bytes(), _field_at(WritePoint, "pos"), b"G")),
)
