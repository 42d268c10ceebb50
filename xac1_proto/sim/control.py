"""Control commands typed on the running simulator's stdin (``xac1 sim``): parse a line, apply it to the
model, return the text to print. No I/O here; the CLI calls ``apply`` under the simulator's lock.

Commands: ``help``, ``status``, ``estop on|off``, ``alarm CODE``, ``fault CODE`` (09, 0B, 0A: next move;
04, 06: next memory access), ``noise P``, ``drop P``, ``delay MS [P]``, ``seed N``, ``slow MS``,
``deviation [NAME [on|off]]``.
"""

from __future__ import annotations

import dataclasses
from typing import Final

from .. import spec
from .config import DEVIATIONS
from .model import MEMORY_FAULTS, MOVE_FAULTS, DeviceModel, Output

HELP: Final = """\
commands:
  status                 show the device state
  estop on|off           emergency stop input (on: every answer becomes 0%%0E)
  alarm CODE             latch an alarm now (hex: 04 06 08 09 0A 0B 0E ...)
  fault CODE             next move fails (09 limit, 0B homing, 0A pulse) or memory access (04, 06)
  noise P | drop P       corrupt / drop each answer byte with probability P (0 turns it off)
  delay MS [P]           delay answers by MS milliseconds (with probability P, default 1)
  seed N                 reseed the line faults
  slow MS                extra turnaround before every answer
  deviation [NAME [off]] list deviations, or switch one on (off)
  help                   this text"""


def _code(text: str) -> int:
    try:
        return int(text, 16)
    except ValueError:
        raise ValueError(f"expected a hex alarm code like 0B, got {text!r}") from None


def _prob(text: str) -> float:
    try:
        p = float(text)
    except ValueError:
        raise ValueError(f"expected a probability 0..1, got {text!r}") from None
    if not 0 <= p <= 1:
        raise ValueError(f"expected a probability 0..1, got {text!r}")
    return p


def _ms(text: str) -> float:
    try:
        ms = float(text)
    except ValueError:
        raise ValueError(f"expected milliseconds, got {text!r}") from None
    if ms < 0:
        raise ValueError(f"expected milliseconds >= 0, got {text!r}")
    return ms / 1000.0


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


def apply(model: DeviceModel, line: str, t: float) -> tuple[str, list[Output]]:
    """Run one control command; (text to show, answers it scheduled). ValueError for a bad command."""
    words = line.split()
    if not words:
        return "", []
    cmd, args = words[0].lower(), words[1:]

    def need(n: int, usage: str) -> None:
        if len(args) != n:
            raise ValueError(f"usage: {usage}")

    if cmd == "help":
        return HELP, []
    if cmd == "status":
        return status_text(model, t), []
    if cmd == "estop":
        need(1, "estop on|off")
        if args[0].lower() not in ("on", "off"):
            raise ValueError("usage: estop on|off")
        on = args[0].lower() == "on"
        outs = model.set_estop(on, t)
        return f"emergency stop {'ON' if on else 'off'}", outs
    if cmd == "alarm":
        need(1, "alarm CODE")
        code = _code(args[0])
        outs = model.raise_alarm(code, t)
        return f"alarm {code:02X} latched ({spec.alarm_meaning(code)})", outs
    if cmd == "fault":
        need(1, "fault CODE")
        code = _code(args[0])
        if code in MOVE_FAULTS:
            model.fail_next_move(code)
            return f"next move fails with {code:02X} ({spec.alarm_meaning(code)})", []
        if code in MEMORY_FAULTS:
            model.fail_next_memory(code)
            return f"next memory access fails with {code:02X} ({spec.alarm_meaning(code)})", []
        raise ValueError(f"fault CODE: one of 09 0B 0A (moves) or 04 06 (memory), got {args[0]}")
    if cmd in ("noise", "drop", "seed", "delay"):
        faults = model.config.faults
        if cmd == "noise":
            need(1, "noise P")
            faults = dataclasses.replace(faults, corrupt=_prob(args[0]))
        elif cmd == "drop":
            need(1, "drop P")
            faults = dataclasses.replace(faults, drop=_prob(args[0]))
        elif cmd == "seed":
            need(1, "seed N")
            faults = dataclasses.replace(faults, seed=int(args[0]))
        else:
            if len(args) not in (1, 2):
                raise ValueError("usage: delay MS [P]")
            p = _prob(args[1]) if len(args) == 2 else (1.0 if _ms(args[0]) else 0.0)
            faults = dataclasses.replace(faults, delay_s=_ms(args[0]), delay=p)
        model.set_line_faults(faults)
        return f"line faults: noise {faults.corrupt} drop {faults.drop} delay {faults.delay_s * 1000:g} ms " \
               f"p={faults.delay} seed {faults.seed}", []
    if cmd == "slow":
        need(1, "slow MS")
        model.slow_turnaround_s = _ms(args[0])
        return f"extra turnaround {model.slow_turnaround_s * 1000:g} ms", []
    if cmd == "deviation":
        if not args:
            enabled = set(model.config.deviations)
            return "\n".join(f"{'*' if n in enabled else ' '} {n:28} {rule}"
                             for n, (rule, _) in DEVIATIONS.items()), []
        if len(args) > 2 or (len(args) == 2 and args[1].lower() not in ("on", "off")):
            raise ValueError("usage: deviation [NAME [on|off]]")
        on_flag = len(args) == 1 or args[1].lower() == "on"
        model.set_deviation(args[0], on_flag)
        return f"deviation {args[0]} {'on' if on_flag else 'off'}", []
    raise ValueError(f"unknown control command {cmd!r}; type help")
