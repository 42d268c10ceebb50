"""``xac1 console``: drive a controller by hand, one named command or raw frame a line.

With a terminal the prompt is prompt_toolkit's (history, tab completion); without one (stdin a pipe or
a file) lines are read plainly, so scripts can drive it too. Moving commands ask for confirmation
unless ``--yes``. A port that goes away ends the console at once (a script must not carry on as if its
commands had been sent).

Exit status: 0 ended by ``quit`` or the end of input; 4 the port could not be opened or went away;
2 bad options.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..client import Client
    from ..console.commands import Plan

EXIT_OK, EXIT_PORT = 0, 4

HELP = "interactive console: named commands (read 3, home, go ...), raw frames (!0RV), history, help"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", required=True, metavar="URL",
                   help="serial device or pyserial URL (/dev/ttyUSB0, socket://host:port, xac1sim://)")
    p.add_argument("--yes", action="store_true", help="do not ask before commands that move the axis")
    p.add_argument("--timeout", type=float, default=0.5, help="turnaround timeout in seconds (default 0.5)")
    p.add_argument("--time-scale", type=float, default=1.0,
                   help="scale of move timeouts (a simulator running faster than real time)")
    p.add_argument("--history", metavar="FILE", help="keep the command history in FILE across sessions")


def _reader(history: str | None) -> tuple[Callable[[str], str], Callable[[str], str]]:
    """Functions that read one line after a prompt (EOFError at the end): command lines, and answers
    to questions (kept out of the history)."""
    if not sys.stdin.isatty():
        def plain(prompt: str) -> str:
            print(prompt, end="", flush=True)
            line = sys.stdin.readline()
            if not line:
                raise EOFError
            print(line.rstrip("\r\n"))  # echoed, so a transcript reads like a session
            return line.rstrip("\r\n")
        return plain, plain
    from prompt_toolkit import PromptSession
    from prompt_toolkit.completion import NestedCompleter, WordCompleter
    from prompt_toolkit.history import FileHistory, InMemoryHistory

    from ..console.commands import COMMANDS

    nested: dict[str, object] = {name: None for name in COMMANDS}
    for name, cmd in COMMANDS.items():
        if cmd.keys:
            nested[name] = WordCompleter([k + "=" for k in cmd.keys])
    nested["help"] = WordCompleter(list(COMMANDS))
    session: PromptSession[str] = PromptSession(
        history=FileHistory(history) if history else InMemoryHistory(),
        completer=NestedCompleter.from_nested_dict(nested), complete_while_typing=False)
    return session.prompt, PromptSession[str](history=InMemoryHistory()).prompt


class PortLost(Exception):
    """The port went away while a command was sent or answered; the message says how."""


def run(args: argparse.Namespace) -> int:
    import serial

    from ..client import Client
    from ..console.show import port_problem

    try:
        client = Client(args.port, timeout=args.timeout, time_scale=args.time_scale)
    except (serial.SerialException, OSError, ValueError) as exc:
        print(f"xac1 console: cannot open {args.port}: {port_problem(exc)}", file=sys.stderr)
        return EXIT_PORT
    read_line, ask = _reader(args.history)
    print(f"xac1 console on {args.port} (9600 8N1). Type help for the commands, quit to leave.")
    with client:
        while True:
            try:
                line = read_line("xac1> ")
            except EOFError:
                print()
                return EXIT_OK
            except KeyboardInterrupt:  # Ctrl-C at the prompt clears the line, as in a shell
                continue
            try:
                if not _run_line(client, line, ask, args.yes):
                    return EXIT_OK
            except KeyboardInterrupt:
                print("interrupted (a move under way cannot be stopped over the line)")
            except PortLost as exc:
                print(f"xac1 console: port {args.port}: {exc}; the console ends", file=sys.stderr)
                return EXIT_PORT


def _run_line(client: Client, line: str, ask: Callable[[str], str], yes: bool) -> bool:
    """Run one console line; False when the console should end."""
    from ..console.commands import UsageError, parse_line

    try:
        plan = parse_line(line)
        if plan is None:
            return True
        if plan.local in _LOCAL:
            return _LOCAL[plan.local](client, plan)
    except UsageError as exc:
        print(f"error: {exc}")
        return True
    raws = [plan.raw] if plan.raw is not None else [f.to_bytes() for f in plan.frames]
    if plan.moves and not yes and not _move_confirmed(raws, ask):
        print("not sent")
        return True
    if all(_send(client, raw) for raw in raws) and plan.local == "status":
        print(f"  communication errors in a row: {client.comm_errors_in_row}"
              f"{' (HALTED: type rearm)' if client.halted else ''}; last known position: "
              f"{'unknown' if client.position is None else client.position}")
    return True


def _help(client: Client, plan: Plan) -> bool:
    """``help [command]``: the commands, or one command's form."""
    from ..console.commands import help_text

    print(help_text(plan.topic))
    return True


def _rearm(client: Client, plan: Plan) -> bool:
    """``rearm``: send commands again after the client halted on communication errors."""
    client.rearm()
    print("rearmed: commands will be sent again")
    return True


def _quit(client: Client, plan: Plan) -> bool:
    """``quit``: the console ends."""
    return False


# The commands the console answers itself, sending nothing; each says whether the console goes on.
_LOCAL: dict[str | None, Callable[[Client, Plan], bool]] = {"help": _help, "rearm": _rearm, "quit": _quit}


def _move_confirmed(raws: list[bytes], ask: Callable[[str], str]) -> bool:
    """Whether the operator answers yes to the frames that move the axis (the end of input is a no)."""
    try:
        shown = " ".join(r.decode("latin-1").strip() for r in raws)
        answer = ask(f"this moves the axis ({shown}); go ahead? [y/N] ")
    except EOFError:
        answer = ""
    return answer.strip().lower() in ("y", "yes")


def _send(client: Client, raw: bytes) -> bool:
    """Send one frame and show it and its answer; False when the rest of the line is not sent (no
    answer, the client halted, an alarm, with a hint of what to do). PortLost when the port went away."""
    from ..console.show import answer_lines, error_line, port_problem, sent_lines
    from ..errors import AlarmError, CommunicationHalted, ResponseTimeout, XAC1Error
    from ..exchange import answer_or_raise
    from ..spec import ALARM_ESTOP

    print("\n".join(sent_lines(raw)), flush=True)
    try:
        ex = client.transact(raw)
    except (ResponseTimeout, CommunicationHalted) as exc:
        print(error_line(exc))
        if isinstance(exc, CommunicationHalted):
            print("  check the equipment and the cable, then type rearm")
        return False
    except OSError as exc:  # pyserial's SerialException too: the port went away
        raise PortLost(port_problem(exc)) from None
    print("\n".join(answer_lines(ex)), flush=True)
    try:
        answer_or_raise(ex)
    except AlarmError as exc:
        hint = ("release the emergency stop input, then reset and home" if exc.code == ALARM_ESTOP
                else "type reset to clear it")
        print(f"  ({hint})")
        return False
    except XAC1Error:
        return False
    return True
