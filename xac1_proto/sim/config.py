"""The simulator's settings in one place: every docs/protocol.md silent-point choice, line faults, deviations.

``SimConfig`` holds the defaults docs/protocol.md "Where the vendor text is silent" fixes; each field names
the silent item it covers, so a test can run the simulator with other choices. ``LineFaults`` spoils
answer bytes on the way out (seedable). ``DEVIATIONS`` lists the named ways to break one *stated* rule
on purpose (the conformance suite proves itself against them); they are not faults a device may have.

``config_from_options`` turns string options (a ``xac1sim://`` query string, ``xac1 sim`` flags) into a
``SimConfig`` with a clear error for unknown names or bad values; ``OPTIONS`` documents them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Final

from .. import spec
from ..framer import MAX_FRAME
from ..motion import DEFAULT_SPEEDS, SpeedTable

# Bounds on times the simulator waits (a wait beyond them is a typo, not a test): non-finite or absurd
# values would make the simulator's loop sleep for ever or die; they are refused where they enter.
MAX_WAIT_MS: Final = 60_000.0  # turnaround, answer delay, the ``slow`` control command
MAX_TIME_SCALE: Final = 1000.0


def parse_ms(text: str) -> float:
    """Milliseconds 0..MAX_WAIT_MS as seconds; ValueError saying what was expected."""
    try:
        ms = float(text)
    except ValueError:
        raise ValueError(f"expected milliseconds, got {text!r}") from None
    if not (math.isfinite(ms) and 0 <= ms <= MAX_WAIT_MS):
        raise ValueError(f"expected milliseconds 0..{MAX_WAIT_MS:g}, got {text!r}")
    return ms / 1000.0


def parse_probability(text: str) -> float:
    """A probability 0..1; ValueError saying what was expected."""
    try:
        p = float(text)
    except ValueError:
        raise ValueError(f"expected a probability 0..1, got {text!r}") from None
    if not 0 <= p <= 1:  # also false for NaN
        raise ValueError(f"expected a probability 0..1, got {text!r}")
    return p


def parse_time_scale(text: str) -> float:
    """A time scale 0..MAX_TIME_SCALE (0 = instant)."""
    try:
        f = float(text)
    except ValueError:
        raise ValueError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(f) and 0 <= f <= MAX_TIME_SCALE):
        raise ValueError(f"expected a time scale 0..{MAX_TIME_SCALE:g} (0 = instant), got {text!r}")
    return f


def _check_wait(name: str, seconds: float) -> None:
    if not (math.isfinite(seconds) and 0 <= seconds <= MAX_WAIT_MS / 1000.0):
        raise ValueError(f"{name} must be 0..{MAX_WAIT_MS:g} ms, got {seconds * 1000:g} ms")


# name -> (rule broken, docs/protocol.md section). Each deviation breaks exactly one stated rule.
DEVIATIONS: Final[dict[str, tuple[str, str]]] = {
    "no-2": ("answers that carry the mandatory `2` are sent without it (one byte short)",
             "Fields; Frames"),
    "wrong-length": ("every answer gets one extra space before CR LF", "Frames (byte counts)"),
    "echo-differs": ("echo answers (0WP, 0MV, 0WS, 0CM) differ from the command in one field "
                     "(Pos, Pos, O, m); the command itself is carried out as sent",
                     "Frames (same as the command)"),
    "alarm-not-latched": ("an alarm (other than emergency stop) is answered once, then forgotten",
                          "Behaviour the vendor text states (latched alarm)"),
    "wrong-reset-answer": ("0%C answers `0%C01` instead of `0%C00` (the reset still happens)",
                           "Frames (0%C); Behaviour the vendor text states (alarm reset)"),
    "rc-before-homing-not-ffffff": ("0RC before homing answers Pos `000000` instead of `FFFFFF`",
                                    "Behaviour the vendor text states (0RC before homing)"),
    "write-not-stored": ("0WP and 0WC answer as usual but the point table is not changed",
                         "Frames (0WP write, 0WC store)"),
    "outputs-not-stored": ("0WS echoes but the OUT ports are not changed", "Frames (0WS)"),
    "move-not-performed": ("0MP/0MV answer as usual but the axis stays where it was (homing itself "
                           "still happens)", "Frames (0MP, 0MV); Behaviour the vendor text states (moves)"),
    "lf-only": ("answers end with LF only, no CR", "Framing (CR LF)"),
    "letter-o": ("answers start with the letter `O` instead of the digit `0`", "Framing (leading 0)"),
    "silent-on-malformed": ("a malformed command latches alarm 01 but gets no answer",
                            "Behaviour the vendor text states (errors get an error answer); silent item 1"),
    "swapped-fields": ("point answers of 0RP, 0RC, 0WC, 0MP carry V and A swapped (invisible when "
                       "V = A)", "Frames (0RP N V A O 2 Pos)"),
    "wrong-n": ("answers of 0RP, 0WC, 0MP carry another N (N + 1)", "Frames (answers carry N)"),
    "estop-cleared": ("0%C clears emergency stop and answers `0%C00`",
                      "Behaviour the vendor text states (reset clears all but 0E)"),
}

# name -> what a robust controller would not do: faults of robustness, switched on like a deviation
# (``deviation=NAME``) but no stated rule's test: ``xac1 fuzz`` finds them (docs/fuzz.md). Each stays
# until a power cycle (a new simulator).
ROBUSTNESS: Final[dict[str, str]] = {
    "hang-on-long-line": "a line longer than hang_bytes (default 40) hangs it: nothing more is answered",
    "nul-corrupts-point": "a NUL byte in a line flips bit 8 of point 1's stored Pos",
    "late-after-errors": "flood_errors (default 3) malformed lines in a row leave every answer 0.5 s late",
}
LATE_AFTER_ERRORS_S: Final = 0.5  # how late ``late-after-errors`` answers (not scaled by time_scale)
ROBUSTNESS_MARK: Final = "robustness fault: the conformance suite does not check it; xac1 fuzz finds it"


def deviation_listing() -> list[tuple[str, str]]:
    """Every name ``deviation`` takes with what it does: each deviation with the docs/protocol.md section
    of the rule it breaks, then each robustness fault marked as one (``xac1 sim --deviation list`` and
    the control channel's ``deviation`` show this)."""
    stated = [(name, f"{rule} [docs/protocol.md: {section}]") for name, (rule, section) in DEVIATIONS.items()]
    return stated + [(name, f"{what} [{ROBUSTNESS_MARK}]") for name, what in ROBUSTNESS.items()]


@dataclass(frozen=True)
class LineFaults:
    """Spoil answer bytes on their way out. Probabilities are per byte (corrupt, drop) or per answer
    (delay); ``seed`` makes the spoiling reproducible."""

    corrupt: float = 0.0  # a byte's bits are flipped
    drop: float = 0.0  # a byte is lost
    delay: float = 0.0  # an answer (and those behind it) comes ``delay_s`` late
    delay_s: float = 0.1
    seed: int | None = None

    def __post_init__(self) -> None:
        for name in ("corrupt", "drop", "delay"):
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:  # also false for NaN
                raise ValueError(f"line fault {name}: probability must be 0..1, got {p}")
        _check_wait("line fault delay", self.delay_s)

    @property
    def active(self) -> bool:
        return bool(self.corrupt or self.drop or self.delay)


@dataclass(frozen=True)
class SimConfig:
    """Everything the simulator may be told; defaults are docs/protocol.md's choices."""

    version: str = "100"  # 0RV's answer, three digits
    time_scale: float = 1.0  # scales motion and turnaround; 0 = instant
    wire_timing: bool = False  # pace answer bytes at 9600 baud (not scaled)
    turnaround_s: float = 0.002  # silent item 17: command's last byte -> answer's first byte
    speeds: SpeedTable = DEFAULT_SPEEDS  # silent item 15
    stroke: tuple[int, int] = (0, spec.UNKNOWN_POSITION - 1)  # silent item 5
    homing_distance: int = 10_000  # pulses homing travels when the position is unknown
    malformed_alarm: int = spec.ALARM_COMM  # silent item 1
    accept_lowercase: bool = False  # silent item 2: lower-case hex is malformed by default
    estop_rehome: bool = True  # silent item 3: after estop release the axis must home again
    store_before_homing_alarm: int = spec.ALARM_POSITION  # silent item 4
    position_alarm: int = spec.ALARM_POSITION  # silent item 5: beyond the stroke, unwritten point
    unwritten_point: tuple[int, int, int, int] = (0, 0, 0, 0)  # silent item 6: V, A, O, Pos
    point_move_sets_outputs: bool = True  # silent item 8
    discard_during_move: bool = True  # silent item 10 (False: bytes wait until the answer is sent)
    cm0_sticky: bool = False  # silent item 11 (True: mode 0 stays until the next 0CM1)
    faults: LineFaults = field(default_factory=LineFaults)
    deviations: frozenset[str] = frozenset()
    hang_bytes: int = 40  # hang-on-long-line: longest line still answered (1..63, below the framer's limit)
    flood_errors: int = 3  # late-after-errors: malformed lines in a row that make it late

    def __post_init__(self) -> None:
        if not (len(self.version) == 3 and self.version.isdigit() and self.version.isascii()):
            raise ValueError(f"version must be three digits (100 = 1.00), got {self.version!r}")
        if not (math.isfinite(self.time_scale) and 0 <= self.time_scale <= MAX_TIME_SCALE):
            raise ValueError(f"time_scale must be 0..{MAX_TIME_SCALE:g}, got {self.time_scale}")
        _check_wait("turnaround", self.turnaround_s)
        lo, hi = self.stroke
        if not 0 <= lo <= hi < spec.UNKNOWN_POSITION:
            raise ValueError(f"stroke must be LO:HI with 0 <= LO <= HI <= 0xFFFFFE, got {lo:#x}:{hi:#x}")
        unknown = sorted(set(self.deviations) - set(DEVIATIONS) - set(ROBUSTNESS))
        if unknown:
            raise ValueError(f"unknown deviation {', '.join(unknown)}; known: "
                             f"{', '.join([*DEVIATIONS, *ROBUSTNESS])}")
        if not 1 <= self.hang_bytes < MAX_FRAME:
            raise ValueError(f"hang_bytes must be 1..{MAX_FRAME - 1}, got {self.hang_bytes}")
        if self.flood_errors < 1:
            raise ValueError(f"flood_errors must be a positive count, got {self.flood_errors}")
        object.__setattr__(self, "deviations", frozenset(self.deviations))

    def replace(self, **changes: object) -> SimConfig:
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


# ---- string options: one table for the xac1sim:// query string and the CLI ----

OPTIONS: Final[dict[str, str]] = {
    "time_scale": "float 0..1000; motion and turnaround scale, 0 = instant (default 1)",
    "wire_timing": "0/1; pace answers at 9600 baud (default 0)",
    "version": "three digits, 0RV's answer (default 100)",
    "turnaround": "milliseconds (0..60000) from a command's last byte to its answer (default 2)",
    "stroke": "LO:HI positions a move may reach, decimal or 0x-hex (default 0:0xFFFFFE)",
    "deviation": "a name from DEVIATIONS or ROBUSTNESS; repeat or comma-separate for several",
    "hang_bytes": "int 1..63; the longest line hang-on-long-line still answers (default 40)",
    "flood_errors": "int >= 1; malformed lines in a row that make late-after-errors late (default 3)",
    "seed": "int; seeds the line faults",
    "noise": "probability a sent byte is corrupted",
    "drop": "probability a sent byte is lost",
    "delay": "milliseconds (0..60000) an answer is delayed (with probability delay_p, default 1)",
    "delay_p": "probability an answer is delayed",
    "accept_lowercase": "0/1; silent item 2",
    "estop_rehome": "0/1; silent item 3",
    "point_move_sets_outputs": "0/1; silent item 8",
    "discard_during_move": "0/1; silent item 10",
    "cm0_sticky": "0/1; silent item 11",
    "malformed_alarm": "hex alarm code for malformed commands (default 01)",
    "position_alarm": "hex alarm code for moves beyond the stroke or to unwritten points (default 08)",
    "store_before_homing_alarm": "hex alarm code for 0WC before homing (default 08)",
}


def parse_int(text: str) -> int:
    """Decimal or 0x-hex."""
    return int(text, 16) if text.lower().startswith("0x") else int(text, 10)


def _bool(text: str) -> bool:
    low = text.strip().lower()
    if low in ("1", "true", "yes", "on"):
        return True
    if low in ("0", "false", "no", "off"):
        return False
    raise ValueError(f"expected 0 or 1, got {text!r}")


def _stroke(text: str) -> tuple[int, int]:
    """``LO:HI``, each decimal or 0x-hex."""
    lo, _, hi = text.partition(":")
    return parse_int(lo), parse_int(hi)


def _seed(text: str) -> int:
    """A signed decimal integer."""
    if not text.strip().lstrip("-").isdigit():
        raise ValueError(f"expected an integer, got {text!r}")
    return int(text)


def _whole(text: str) -> int:
    """A whole decimal number."""
    if not text.strip().isdigit():
        raise ValueError(f"expected a whole number, got {text!r}")
    return int(text)


def _alarm_code(text: str) -> int:
    """A hex alarm code."""
    return int(text, 16)


# Option -> (the config's or its line faults' field it sets, the parser of its text). Options not
# named here: ``deviation`` (collected), ``*_alarm`` (hex codes) and the 0/1 switches.
_CONFIG_FIELDS: Final[dict[str, tuple[str, Callable[[str], object]]]] = {
    "time_scale": ("time_scale", parse_time_scale), "version": ("version", str),
    "turnaround": ("turnaround_s", parse_ms), "stroke": ("stroke", _stroke),
    "hang_bytes": ("hang_bytes", _whole), "flood_errors": ("flood_errors", _whole),
}
_FAULT_FIELDS: Final[dict[str, tuple[str, Callable[[str], object]]]] = {
    "seed": ("seed", _seed), "noise": ("corrupt", parse_probability), "drop": ("drop", parse_probability),
    "delay": ("delay_s", parse_ms), "delay_p": ("delay", parse_probability),
}


def config_from_options(options: Mapping[str, str | Iterable[str]],
                        base: SimConfig | None = None) -> SimConfig:
    """A config from string options (see ``OPTIONS``); raises ValueError naming the bad option."""
    cfg = base or SimConfig()
    changes: dict[str, object] = {}
    faults: dict[str, object] = {}
    deviations = set(cfg.deviations)
    for name, raw in options.items():
        values = [raw] if isinstance(raw, str) else list(raw)
        if name not in OPTIONS:
            raise ValueError(f"unknown simulator option {name!r}; known: {', '.join(OPTIONS)}")
        value = values[-1]
        try:
            if name == "deviation":
                deviations.update(x.strip() for v in values for x in v.split(",") if x.strip())
            elif name in _FAULT_FIELDS:
                key, parse = _FAULT_FIELDS[name]
                faults[key] = parse(value)
            else:
                switch = (name, _alarm_code if name.endswith("_alarm") else _bool)
                key, parse = _CONFIG_FIELDS.get(name, switch)
                changes[key] = parse(value)
        except ValueError as exc:
            raise ValueError(f"simulator option {name}={value!r}: {exc}") from None
    if "delay_s" in faults:
        faults.setdefault("delay", 1.0)  # a delay without its probability delays every answer
    if faults:
        changes["faults"] = dataclasses.replace(cfg.faults, **faults)  # type: ignore[arg-type]
    changes["deviations"] = frozenset(deviations)
    return dataclasses.replace(cfg, **changes)  # type: ignore[arg-type]
