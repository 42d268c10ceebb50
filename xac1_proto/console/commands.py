"""The console's command language, parsed into a plan of frames to send (no I/O).

A line is a named command with arguments (``read 3``, ``write 1 v=9 a=3 o=0 pos=0x12345``,
``go vel=30 a=2 pos=5000``) or a raw frame after ``!`` (``!0RV``). Numbers are decimal or ``0x`` hex;
a point number may also be one hex digit (``read A``). Frames are built through the frame classes, so
the spec's ranges are checked here, before anything is sent; moving commands are flagged for the
console to confirm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..codec import diagnose
from ..errors import FrameError
from ..frames import (
    AlarmReset,
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
from .show import command_bytes


class UsageError(ValueError):
    """A console line that cannot be run; the message says what was expected."""


@dataclass(frozen=True)
class Plan:
    """What a line asks for: frames to send in order, or raw bytes, or a local action."""

    frames: tuple[Frame, ...] = ()
    raw: bytes | None = None
    local: str | None = None  # "help", "quit", "rearm", "status" (status also sends frames)
    topic: str | None = None  # help's argument
    moves: bool = False


@dataclass(frozen=True)
class Command:
    usage: str
    help: str
    keys: tuple[str, ...] = ()  # key=value arguments, all required


def _number(name: str, text: str, hex_digit: bool = False) -> int:
    try:
        return int(text, 0)
    except ValueError:
        if hex_digit and len(text) == 1 and text.upper() in "ABCDEF":
            return int(text, 16)
    digit = ", or one hex digit" if hex_digit else ""
    raise UsageError(f"{name} must be a number (decimal, or hex with 0x{digit}), got {text!r}")


def _keys(cmd: str, words: list[str], keys: tuple[str, ...]) -> dict[str, Any]:
    """``KEY=VALUE`` words as a frame's keyword arguments (ints; the frame checks their ranges)."""
    values: dict[str, Any] = {}
    for word in words:
        key, eq, text = word.partition("=")
        if not eq or key not in keys:
            raise UsageError(f"{cmd}: expected {' '.join(k + '=...' for k in keys)}, got {word!r}")
        values[key] = _number(key, text)
    missing = [k for k in keys if k not in values]
    if missing:
        raise UsageError(f"{cmd}: missing {', '.join(k + '=' for k in missing)} "
                         f"(usage: {COMMANDS[cmd].usage})")
    return values


def _one(cmd: str, words: list[str], what: str, hex_digit: bool = False) -> int:
    if len(words) != 1:
        raise UsageError(f"{cmd}: expected {what} (usage: {COMMANDS[cmd].usage}), got "
                         f"{' '.join(words)!r}" if words else f"{cmd}: expected {what} (usage: "
                         f"{COMMANDS[cmd].usage})")
    return _number(what, words[0], hex_digit)


def _raw(text: str) -> Plan:
    try:
        raw = command_bytes(text)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    frame, _ = diagnose(raw, "command")
    return Plan(raw=raw, moves=isinstance(frame, (MovePoint, MoveDirect)))


COMMANDS: dict[str, Command] = {
    "read": Command("read N", "0RP: read movement data of point N (1-F)"),
    "write": Command("write N v=V a=A o=O pos=POS", "0WP: write point N (V 1-9, A 1-3, O 0-3, POS pulses)",
                     ("v", "a", "o", "pos")),
    "current": Command("current", "0RC: read the current position"),
    "store": Command("store N", "0WC: store the current position into point N (1-F)"),
    "home": Command("home", "0MP 0: homing (moves the axis)"),
    "move": Command("move N", "0MP: move to point N (moves the axis; 0 homes)"),
    "go": Command("go vel=VEL a=A pos=POS", "0MV: direct move, VEL 1-60, A 1-3 (moves the axis)",
                  ("vel", "a", "pos")),
    "outputs": Command("outputs [O]", "0RS: read the OUT ports; with O (0-3), 0WS: write them"),
    "version": Command("version", "0RV: read the firmware version"),
    "mode": Command("mode M", "0CM: switch mode (0 external start, 1 communication)"),
    "reset": Command("reset", "0%C: alarm reset (emergency stop is not cleared)"),
    "status": Command("status", "0RC and 0RS, and the client's state (communication errors in a row)"),
    "rearm": Command("rearm", "allow sending again after a communication-error storm"),
    "raw": Command("raw FRAME  or  !FRAME", "send FRAME as is (CR LF added unless it ends with \\n)"),
    "help": Command("help [COMMAND]", "list the commands, or explain one"),
    "quit": Command("quit", "leave the console (also: exit, Ctrl-D)"),
}

def _write(c: str, w: list[str]) -> Plan:
    n = _one(c, w[:1], "N", True)
    return Plan(frames=(WritePoint(n=n, **_keys(c, w[1:], COMMANDS[c].keys)),))


def _outputs(c: str, w: list[str]) -> Plan:
    return Plan(frames=(WriteOutputs(o=_one(c, w, "O")),) if w else (ReadOutputs(),))


def _plain(plan: Plan) -> Callable[[str, list[str]], Plan]:
    """A command without arguments."""
    def build(c: str, w: list[str]) -> Plan:
        if w:
            raise UsageError(f"{c}: takes no arguments, got {' '.join(w)!r}")
        return plan
    return build


_BUILDERS: dict[str, Callable[[str, list[str]], Plan]] = {
    "read": lambda c, w: Plan(frames=(ReadPoint(n=_one(c, w, "N", True)),)),
    "write": _write,
    "current": _plain(Plan(frames=(ReadCurrent(),))),
    "store": lambda c, w: Plan(frames=(StoreCurrent(n=_one(c, w, "N", True)),)),
    "home": _plain(Plan(frames=(MovePoint(n=0),), moves=True)),
    "move": lambda c, w: Plan(frames=(MovePoint(n=_one(c, w, "N", True)),), moves=True),
    "go": lambda c, w: Plan(frames=(MoveDirect(**_keys(c, w, COMMANDS[c].keys)),), moves=True),
    "outputs": _outputs,
    "version": _plain(Plan(frames=(ReadVersion(),))),
    "mode": lambda c, w: Plan(frames=(SwitchMode(mode=_one(c, w, "M")),)),
    "reset": _plain(Plan(frames=(AlarmReset(),))),
    "status": _plain(Plan(frames=(ReadCurrent(), ReadOutputs()), local="status")),
    "rearm": _plain(Plan(local="rearm")),
    "help": lambda c, w: Plan(local="help", topic=w[0] if w else None),
    "quit": _plain(Plan(local="quit")),
    "exit": _plain(Plan(local="quit")),
}


def parse_line(line: str) -> Plan | None:
    """The plan for one console line (None for a blank line); ``UsageError`` says what is wrong."""
    text = line.strip()
    if not text:
        return None
    if text.startswith("!"):
        return _raw(text[1:].strip())
    name, _, rest = text.partition(" ")
    if name == "raw":
        return _raw(rest.strip())
    builder = _BUILDERS.get(name.lower())
    if builder is None:
        raise UsageError(f"unknown command {name!r}; type help for the list")
    try:
        return builder(name.lower(), rest.split())
    except FrameError as exc:
        raise UsageError(f"{name}: {exc}") from None


def help_text(topic: str | None = None) -> str:
    """The command list, or one command's usage."""
    if topic is not None:
        cmd = COMMANDS.get(topic)
        if cmd is None:
            raise UsageError(f"help: no command {topic!r}; type help for the list")
        return f"{cmd.usage}\n  {cmd.help}"
    width = max(len(c.usage) for c in COMMANDS.values())
    lines = [f"  {c.usage:<{width}}  {c.help}" for c in COMMANDS.values()]
    return ("commands (numbers: decimal or 0x hex; N may be one hex digit):\n" + "\n".join(lines)
            + "\nexamples: read 3 | write 1 v=9 a=3 o=0 pos=0x12345 | go vel=30 a=2 pos=5000 | !0RV")
