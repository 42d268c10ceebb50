"""Control commands typed on the running simulator's stdin (``xac1 sim``): parse a line, apply it to the
model, return the text to print. No I/O here: ``ControlChannel`` runs a line on a running simulator
under its lock (``RunningSim.call``), for the stdin channel and the front panel alike.

Commands: ``help``, ``status``, ``estop on|off``, ``power``, ``alarm CODE``, ``fault CODE`` (09, 0B,
0A: next move; 04, 06: next memory access), ``noise P``, ``drop P``, ``delay MS [P]``, ``seed N``,
``slow MS``, ``deviation [NAME [on|off]]``, ``replay`` (where a ``--replay`` run stands in its capture).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from .. import spec
from .config import MAX_WAIT_MS, deviation_listing, parse_ms, parse_probability
from .model import MEMORY_FAULTS, MOVE_FAULTS, DeviceModel, Output

if TYPE_CHECKING:
    from .runner import RunningSim


def _code(text: str) -> int:
    try:
        return int(text, 16)
    except ValueError:
        raise ValueError(f"expected a hex alarm code like 0B, got {text!r}") from None


def _on_off(text: str) -> bool:
    low = text.lower()
    if low not in ("on", "off"):
        raise ValueError(f"expected on or off, got {text!r}")
    return low == "on"


def status_text(model: DeviceModel, t: float) -> str:
    s = model.status(t)
    pos = "unknown (FFFFFF)" if s["position"] is None else f"{s['position']:06X} ({s['position']})"
    alarm = "none" if s["alarm"] is None else f"{s['alarm']:02X} ({spec.alarm_meaning(s['alarm'])})"
    f = s["line_faults"]
    pending = ", ".join(f"{k} {v:02X}" for k, v in s["pending_faults"].items() if v is not None)
    lines = [
        f"mode {s['mode']}  homed {'yes' if s['homed'] else 'no'}  position {pos}"
        f"{'  MOVING' if s['moving'] else ''}",
        f"last move N/V/A {s['last_move']}  OUT {s['outputs']}  alarm {alarm}"
        f"  estop {'ON' if s['estop'] else 'off'}  version {s['version']}",
        f"line faults: noise {f.corrupt} drop {f.drop} delay {f.delay_s * 1000:g} ms p={f.delay}"
        f" seed {f.seed}  slow {s['slow_turnaround_s'] * 1000:g} ms",
        f"pending faults: {pending or 'none'}  deviations: {', '.join(s['deviations']) or 'none'}",
        f"commands {s['commands']}  bytes discarded during moves {s['discarded']}",
        "points: " + (", ".join(f"{n:X}=V{v}A{a}O{o}:{p:06X}" for n, (v, a, o, p) in s["points"].items())
                      or "none written"),
    ]
    return "\n".join(lines)


Result = tuple[str, list[Output]]


@dataclass(frozen=True)
class Control:
    """One control command: its usage line, what it does, how many words it takes, and the action."""

    usage: str
    help: str
    nargs: tuple[int, ...]  # accepted numbers of arguments
    run: Callable[[DeviceModel, list[str], float], Result]


def _estop(model: DeviceModel, args: list[str], t: float) -> Result:
    on = _on_off(args[0])
    already = " (it already was)" if model.estop == on else ""
    return f"emergency stop {'ON' if on else 'off'}{already}", model.set_estop(on, t)


def _power(model: DeviceModel, args: list[str], t: float) -> Result:
    return "power-cycled: not homed, mode 0, OUT ports off, the position table kept", model.power_cycle()


def _alarm(model: DeviceModel, args: list[str], t: float) -> Result:
    code = _code(args[0])
    outs = model.raise_alarm(code, t)
    return f"alarm {code:02X} latched ({spec.alarm_meaning(code)})", outs


def _fault(model: DeviceModel, args: list[str], t: float) -> Result:
    code = _code(args[0])
    if code in MOVE_FAULTS:
        model.fail_next_move(code)
        return f"next move fails with {code:02X} ({spec.alarm_meaning(code)})", []
    if code in MEMORY_FAULTS:
        model.fail_next_memory(code)
        return f"next memory access fails with {code:02X} ({spec.alarm_meaning(code)})", []
    raise ValueError(f"one of 09 0B 0A (moves) or 04 06 (memory), got {args[0]}")


def _line_faults(model: DeviceModel, changes: dict[str, object]) -> Result:
    faults = dataclasses.replace(model.config.faults, **changes)  # type: ignore[arg-type]
    model.set_line_faults(faults)
    return (f"line faults: noise {faults.corrupt} drop {faults.drop} delay {faults.delay_s * 1000:g} ms "
            f"p={faults.delay} seed {faults.seed}"), []


def _seed(model: DeviceModel, args: list[str], t: float) -> Result:
    try:
        seed = int(args[0])
    except ValueError:
        raise ValueError(f"expected an integer seed, got {args[0]!r}") from None
    return _line_faults(model, {"seed": seed})


def _delay(model: DeviceModel, args: list[str], t: float) -> Result:
    delay_s = parse_ms(args[0])
    p = parse_probability(args[1]) if len(args) == 2 else (1.0 if delay_s else 0.0)
    return _line_faults(model, {"delay_s": delay_s, "delay": p})


def _slow(model: DeviceModel, args: list[str], t: float) -> Result:
    model.slow_turnaround_s = parse_ms(args[0])
    return f"extra turnaround {model.slow_turnaround_s * 1000:g} ms", []


def _deviation(model: DeviceModel, args: list[str], t: float) -> Result:
    if not args:
        enabled = set(model.config.deviations)
        rows = deviation_listing()
        return "\n".join(f"{'*' if n in enabled else ' '} {n:28} {what}" for n, what in rows), []
    on = _on_off(args[1]) if len(args) == 2 else True
    model.set_deviation(args[0], on)
    return f"deviation {args[0]} {'on' if on else 'off'}", []


def _replay(model: DeviceModel, args: list[str], t: float) -> Result:
    from .replaying import ReplayingDevice

    if not isinstance(model, ReplayingDevice):
        raise ValueError("not replaying a capture (start the simulator with --replay CAPTURE)")
    return model.replay_where(), []


# The one table of control commands: ``help`` and ``apply`` are both made from it.
CONTROLS: Final[dict[str, Control]] = {
    "status": Control("status", "show the device state", (0,),
                      lambda m, a, t: (status_text(m, t), [])),
    "estop": Control("estop on|off", "emergency stop input (on: every answer becomes 0%%0E)", (1,), _estop),
    "power": Control("power", "switch the unit off and on (the position table is kept)", (0,), _power),
    "alarm": Control("alarm CODE", "latch an alarm now (hex: 04 06 08 09 0A 0B 0E ...)", (1,), _alarm),
    "fault": Control("fault CODE", "next move fails (09 limit, 0B homing, 0A pulse) or memory access "
                     "(04, 06)", (1,), _fault),
    "noise": Control("noise P", "corrupt each answer byte with probability P (0 turns it off)", (1,),
                     lambda m, a, t: _line_faults(m, {"corrupt": parse_probability(a[0])})),
    "drop": Control("drop P", "drop each answer byte with probability P (0 turns it off)", (1,),
                    lambda m, a, t: _line_faults(m, {"drop": parse_probability(a[0])})),
    "delay": Control("delay MS [P]", f"delay answers by MS milliseconds (0..{MAX_WAIT_MS:g}; with "
                     "probability P, default 1)", (1, 2), _delay),
    "seed": Control("seed N", "reseed the line faults", (1,), _seed),
    "slow": Control("slow MS", f"extra turnaround before every answer (0..{MAX_WAIT_MS:g} ms)", (1,), _slow),
    "deviation": Control("deviation [NAME [on|off]]", "list deviations and robustness faults (* on), or "
                         "switch one on (off)", (0, 1, 2),
                         _deviation),
    "replay": Control("replay", "where in the capture the replay stands (xac1 sim --replay)", (0,), _replay),
    "help": Control("help", "this text", (0,), lambda m, a, t: (help_text(), [])),
}


def help_text() -> str:
    width = max(len(c.usage) for c in CONTROLS.values())
    return "commands:\n" + "\n".join(f"  {c.usage:<{width}}  {c.help}" for c in CONTROLS.values())


def apply(model: DeviceModel, line: str, t: float) -> Result:
    """Run one control command; (text to show, answers it scheduled). ValueError for a bad command."""
    words = line.split()
    if not words:
        return "", []
    control = CONTROLS.get(words[0].lower())
    if control is None:
        raise ValueError(f"unknown control command {words[0]!r}; type help")
    args = words[1:]
    if len(args) not in control.nargs:
        raise ValueError(f"usage: {control.usage}")
    try:
        return control.run(model, args, t)
    except ValueError as exc:
        raise ValueError(f"{control.usage}: {exc}") from None


# What a control command did that the line cannot show, for an engine that judges the line:
# ("stop-input", pressed, the axis must home again after the release) or ("power-on",).
Fact = tuple[object, ...]


class ControlChannel:
    """Command text in, the text to show out, on a running simulator: the one way the stdin channel and
    the front panel change the device. ``on_fact`` hears what a command did that the line cannot show
    (the stop input changed, the unit was power-cycled). ValueError for a command that cannot apply."""

    def __init__(self, sim: RunningSim, on_fact: Callable[[Fact], None] | None = None) -> None:
        self.sim = sim
        self.on_fact = on_fact

    def __call__(self, line: str) -> str:
        def run(model: DeviceModel, now: float) -> str:
            estop, cycles = model.estop, model.power_cycles
            text, _ = apply(model, line, now)
            if self.on_fact is not None:  # under the lock: in order with the line's bytes
                if model.power_cycles != cycles:
                    self.on_fact(("power-on",))
                if model.estop != estop:
                    self.on_fact(("stop-input", model.estop, model.config.estop_rehome))
            return text

        text: str = self.sim.call(run)
        return text
