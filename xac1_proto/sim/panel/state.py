"""The device state as the front panel's JSON (``GET /api/state``), from the model's ``status`` (sans-IO)."""

from __future__ import annotations

from typing import Any

from ... import spec
from ..config import DEVIATIONS
from ..model import DeviceModel


def _code(code: int | None) -> dict[str, str] | None:
    return None if code is None else {"code": f"{code:02X}", "meaning": spec.alarm_meaning(code)}


def state_of(model: DeviceModel, t: float) -> dict[str, Any]:
    """What the panel shows of ``model`` at ``t`` (the model's clock): plain JSON data. ``position`` is
    None while unknown (not homed); during a move it is where the axis is at ``t``."""
    s = model.status(t)
    faults = s["line_faults"]
    lo, hi = model.config.stroke
    return {
        "position": s["position"], "homed": s["homed"], "moving": s["moving"],
        "alarm": _code(s["alarm"]), "estop": s["estop"], "outputs": s["outputs"], "mode": s["mode"],
        "points": {f"{n:X}": dict(zip(("v", "a", "o", "pos"), point, strict=True))
                   for n, point in s["points"].items()},
        "deviations": s["deviations"],
        "deviation_rules": {name: rule for name, (rule, _) in DEVIATIONS.items()},
        "stroke": [lo, hi], "version": s["version"], "commands": s["commands"],
        "pending_faults": {k: None if v is None else f"{v:02X}" for k, v in s["pending_faults"].items()},
        "pacing": {"slow_ms": s["slow_turnaround_s"] * 1000, "delay_ms": faults.delay_s * 1000,
                   "delay_p": faults.delay, "noise": faults.corrupt, "drop": faults.drop,
                   "time_scale": model.config.time_scale, "wire_timing": model.config.wire_timing},
    }
