"""Motion timing shared by the simulator (how long a move takes) and the client (how long to wait).

The vendor's speed tables are missing (docs/protocol.md silent item 15): by default speed number V n moves
at n x 1,000 pulses/s, direct-move speed vel n at n x 500 pulses/s, and homing at 10,000 pulses/s with
the mid ramp. A move follows a trapezoidal profile whose ramp (0 to full speed) takes the acceleration
number's time (1: 400 ms, 2: 200 ms, 3: 100 ms); a move too short to reach full speed is triangular.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from . import spec


@dataclass(frozen=True)
class SpeedTable:
    """Pulses per second for each speed number, and the homing move. ``guessed``: the table is our guess
    (``DEFAULT_SPEEDS``), not one a user gave: a move's answer window resting on it is a reading (the
    conversation's rule ``late-move-answer``, docs/protocol.md silent items 15, 17)."""

    v_pps: float = 1000.0  # V n -> n * v_pps
    vel_pps: float = 500.0  # vel n -> n * vel_pps
    homing_pps: float = 10_000.0
    homing_accel: int = 2
    guessed: bool = False

    @classmethod
    def parse(cls, text: str) -> SpeedTable:
        """A table a user gives as ``V:VEL:HOMING[:ACCEL]``: pulses/s of speed number V 1, of direct speed
        vel 1, of homing, and homing's acceleration number (1-3, default 2); ValueError naming what is
        wrong."""
        parts = text.split(":")
        if not 3 <= len(parts) <= 4:
            raise ValueError(f"expected V:VEL:HOMING[:ACCEL] (pulses/s of V 1, vel 1 and homing), "
                             f"got {text!r}")
        try:
            v, vel, homing = (float(x) for x in parts[:3])
            accel = int(parts[3]) if len(parts) == 4 else 2
        except ValueError:
            raise ValueError(f"expected numbers in V:VEL:HOMING[:ACCEL], got {text!r}") from None
        if not all(math.isfinite(x) and x > 0 for x in (v, vel, homing)):
            raise ValueError(f"speeds must be positive pulses per second, got {text!r}")
        if accel not in spec.ACCEL_RAMP_S:
            raise ValueError(f"the homing acceleration number is one of {sorted(spec.ACCEL_RAMP_S)}, "
                             f"got {accel}")
        return cls(v, vel, homing, accel)

    def point_speed(self, v: int) -> float:
        return max(v, 1) * self.v_pps

    def direct_speed(self, vel: int) -> float:
        return max(vel, 1) * self.vel_pps


DEFAULT_SPEEDS = SpeedTable(guessed=True)  # silent item 15: the vendor's tables are missing


_LOW_RAMP_S: Final = spec.ACCEL_RAMP_S[1]


def ramp_time(a: int) -> float:
    """Seconds from standstill to full speed for acceleration number ``a`` (0 or unknown: low)."""
    return spec.ACCEL_RAMP_S.get(a, _LOW_RAMP_S)


def move_time(distance: int, speed_pps: float, a: int) -> float:
    """Seconds a trapezoidal move of ``distance`` pulses takes (0 for no distance)."""
    distance = abs(distance)
    if distance == 0:
        return 0.0
    ramp = spec.ACCEL_RAMP_S.get(a, _LOW_RAMP_S)  # ``ramp_time(a)`` (a move's window prices up to three)
    if distance >= speed_pps * ramp:  # reaches full speed: ramp up + cruise + ramp down
        return distance / speed_pps + ramp
    return 2.0 * math.sqrt(distance * ramp / speed_pps)  # triangular


def position_at(start: int, target: int, speed_pps: float, a: int, elapsed: float) -> int:
    """Where a move from ``start`` to ``target`` is after ``elapsed`` seconds."""
    total = move_time(target - start, speed_pps, a)
    if elapsed <= 0 or total == 0:
        return start if elapsed <= 0 else target
    if elapsed >= total:
        return target
    distance = abs(target - start)
    ramp = ramp_time(a)
    accel = speed_pps / ramp
    peak = min(speed_pps, math.sqrt(distance * accel))
    t_ramp = peak / accel
    if elapsed < t_ramp:
        done = 0.5 * accel * elapsed**2
    elif elapsed <= total - t_ramp:
        done = 0.5 * accel * t_ramp**2 + peak * (elapsed - t_ramp)
    else:
        left = total - elapsed
        done = distance - 0.5 * accel * left**2
    step = int(round(min(max(done, 0), distance)))
    return start + step if target >= start else start - step
