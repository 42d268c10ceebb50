"""What a conformance run may do to the device: port, motion, safe range, fresh device, seed.

The rules (docs/conformance.md): the built-in simulator (a ``xac1sim://`` URL) may always move and is
always fresh; a real device moves only with ``--xac1-allow-motion`` and a safe range, and only to
positions inside that range; the power-on checks run only on a device declared fresh; on a real device
the suite writes only points it can write back, plus those named with ``--xac1-scratch-points``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

from xac1_proto import spec
from xac1_proto.rules import DEFAULT_READINGS, READINGS, Readings

SIMULATOR_SCHEME = "xac1sim://"
# The built-in simulator with instant motion: a run against it takes seconds, not minutes.
DEFAULT_PORT = SIMULATOR_SCHEME + "?time_scale=0"
# Where the suite moves the simulator when the user gives no safe range.
SIMULATOR_SAFE_RANGE = (0, 0xFFFF)
DEFAULT_SEED = 0
# The in-process simulator answers at once: silence there (a deviation) is known after a short wait.
SIMULATOR_TIMEOUT_S = 0.2


class SettingsError(ValueError):
    """A bad option value or combination; the message says which and what is expected (named as the
    pytest plugin's options are: ``--xac1-safe-range``)."""

    def in_cli_words(self) -> str:
        """The message as ``xac1 conformance`` and ``xac1 replay`` name their options (``--safe-range``)."""
        return str(self).replace("--xac1-", "--")


def parse_position(text: str, what: str) -> int:
    """A position given as decimal (``4096``) or 0x-hex (``0x1000``), inside 000000-FFFFFE."""
    t = text.strip()
    try:
        value = int(t, 16) if t.lower().startswith("0x") else int(t, 10)
    except ValueError:
        raise SettingsError(f"{what}: expected a decimal or 0x-hex position, got {text!r}") from None
    top = spec.UNKNOWN_POSITION - 1  # FFFFFF is the "unknown position" marker, never a target
    if not 0 <= value <= top:
        raise SettingsError(f"{what}: position {text!r} is outside 0-0x{top:06X}")
    return value


def parse_safe_range(text: str) -> tuple[int, int]:
    """``LO:HI`` (decimal or 0x-hex, LO <= HI) as a pair of ints."""
    lo_text, sep, hi_text = text.partition(":")
    if not sep:
        raise SettingsError(f"--xac1-safe-range: expected LO:HI (e.g. 0:0x1000), got {text!r}")
    lo = parse_position(lo_text, "--xac1-safe-range LO")
    hi = parse_position(hi_text, "--xac1-safe-range HI")
    if lo > hi:
        raise SettingsError(f"--xac1-safe-range: LO 0x{lo:06X} is above HI 0x{hi:06X}")
    return lo, hi


def parse_points(text: str) -> tuple[int, ...]:
    """``1,2,F``: point numbers (one hex digit each, 1-F) the suite may overwrite, in the order given."""
    lo, hi = spec.FIELDS["n"].command_range
    out: list[int] = []
    for part in (t.strip() for t in text.split(",")):
        try:
            n = int(part, 16)
        except ValueError:
            n = -1
        if len(part) != 1 or not lo <= n <= hi:
            raise SettingsError(f"--xac1-scratch-points: expected point numbers {lo:X}-{hi:X} separated by "
                                f"commas (e.g. 1,2,F), got {part!r} in {text!r}")
        if n not in out:
            out.append(n)
    return tuple(out)


def _sim_time_scale(url: str) -> float:
    """The ``time_scale`` of a ``xac1sim://`` URL (1 when absent or unreadable: wait as for real motion)."""
    from urllib.parse import parse_qs, urlsplit

    try:
        return float(parse_qs(urlsplit(url).query).get("time_scale", ["1"])[-1])
    except ValueError:
        return 1.0


def is_simulator(port: str) -> bool:
    return port.startswith(SIMULATOR_SCHEME)


_N = TypeVar("_N", int, float)


def parse_readings(name: str | None) -> Readings:
    """The severity of our readings named by ``--xac1-readings`` (None: the default, notices)."""
    chosen = next((r for r in READINGS if r == (name or DEFAULT_READINGS)), None)
    if chosen is None:
        raise SettingsError(f"--xac1-readings: expected one of {', '.join(READINGS)}, got {name!r}")
    return chosen


def _positive(value: _N | None, flag: str, expected: str) -> _N | None:
    """``value`` when left out or above 0; a SettingsError naming ``flag`` otherwise."""
    if value is not None and value <= 0:
        raise SettingsError(f"{flag}: expected {expected}, got {value}")
    return value


@dataclass(frozen=True)
class _PortKind:
    """What a run assumes of its port for the options left out: the built-in simulator may always move
    (in SIMULATOR_SAFE_RANGE), is always fresh and answers at once; a real device moves only inside a
    range the user gives."""

    safe_range: tuple[int, int] | None
    always_moves: bool
    always_fresh: bool
    examples: int  # random command sequences
    timeout: float  # seconds for an answer


_SIMULATOR = _PortKind(SIMULATOR_SAFE_RANGE, True, True, examples=30, timeout=SIMULATOR_TIMEOUT_S)
_REAL_DEVICE = _PortKind(None, False, False, examples=10, timeout=spec.NO_ANSWER_TIMEOUT_S)


@dataclass(frozen=True)
class Settings:
    """The options of one run, checked for consistency by ``make``."""

    port: str
    simulator: bool
    motion: bool
    fresh: bool
    safe_range: tuple[int, int] | None
    seed: int | None  # None: derandomized (the same sequences every run)
    examples: int
    timeout: float = spec.NO_ANSWER_TIMEOUT_S  # turnaround timeout of one answer, seconds
    time_scale: float = 1.0  # how fast moves run compared with the speed table (the simulator's option)
    scratch_points: tuple[int, ...] = ()  # points the user lets the suite overwrite, even if never written
    restore_mode0: bool = False  # send 0CM0 as the very last command (external start enabled again)
    cli: bool = False  # started by ``xac1 conformance``: name its options (--allow-motion), not pytest's
    readings: Readings = DEFAULT_READINGS  # our readings' severity: notice, or error (``xac1_proto.rules``)

    @classmethod
    def make(cls, port: str | None, allow_motion: bool, fresh: bool, safe_range: str | None,
             seed: int | None = None, examples: int | None = None,
             timeout: float | None = None, scratch_points: str | None = None, restore_mode0: bool = False,
             cli: bool = False, readings: str | None = None) -> Settings:
        port = port or DEFAULT_PORT
        sim = is_simulator(port)
        kind = _SIMULATOR if sim else _REAL_DEVICE
        rng = parse_safe_range(safe_range) if safe_range else kind.safe_range
        motion = allow_motion or kind.always_moves
        if motion and rng is None:
            raise SettingsError("--xac1-allow-motion on a real device needs --xac1-safe-range LO:HI: the "
                                "positions the actuator may be moved to (e.g. --xac1-safe-range 0:0x1000)")
        return cls(port=port, simulator=sim, motion=motion, fresh=fresh or kind.always_fresh, safe_range=rng,
                   seed=DEFAULT_SEED if seed is None else seed,
                   examples=_positive(examples, "--xac1-examples", "a positive count") or kind.examples,
                   timeout=_positive(timeout, "--xac1-timeout", "seconds > 0") or kind.timeout,
                   readings=parse_readings(readings), time_scale=_sim_time_scale(port) if sim else 1.0,
                   scratch_points=parse_points(scratch_points) if scratch_points else (),
                   restore_mode0=restore_mode0, cli=cli)

    def flag(self, name: str) -> str:
        """How the user spells option ``name`` (``allow-motion``) in the command they ran."""
        return f"--{name}" if self.cli else f"--xac1-{name}"

    def in_range(self, pos: int) -> bool:
        return self.safe_range is not None and self.safe_range[0] <= pos <= self.safe_range[1]

    @property
    def may_home(self) -> bool:
        """Homing goes to the origin: allowed only when motion is and the origin is inside the range."""
        return self.motion and self.in_range(0)

    def describe_range(self) -> str:
        if self.safe_range is None:
            return "none (no motion)"
        lo, hi = self.safe_range
        return f"0x{lo:06X}-0x{hi:06X} ({lo}-{hi})"
