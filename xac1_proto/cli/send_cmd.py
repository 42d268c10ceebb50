"""``xac1 send``: one-shot commands from a shell, each shown sent and received, decoded."""

from __future__ import annotations

import argparse
import math
import sys
from typing import NoReturn

HELP = "send raw commands (e.g. 0RV 0RP3) to a controller and show the answers decoded"

# Exit status: the first failure stops the run.
EXIT_ALARM, EXIT_PROTOCOL, EXIT_TIMEOUT, EXIT_PORT, EXIT_USAGE = 1, 2, 3, 4, 5
EXIT_SIGNAL = 130  # Ctrl-C, SIGTERM or SIGHUP while sending (128 + SIGINT, as shells report it)


def _usage(message: str) -> int:
    print(f"xac1 send: {message}", file=sys.stderr)
    return EXIT_USAGE


def add_arguments(p: argparse.ArgumentParser) -> None:
    def usage_error(message: str) -> NoReturn:  # bad input is EXIT_USAGE here, not argparse's 2
        p.print_usage(sys.stderr)
        p.exit(EXIT_USAGE, f"xac1 send: error: {message}\n")

    p.error = usage_error  # type: ignore[method-assign]
    p.add_argument("--port", required=True, metavar="URL",
                   help="serial device or pyserial URL (/dev/ttyUSB0, socket://host:port, xac1sim://)")
    p.add_argument("commands", nargs="*", metavar="CMD",
                   help="a frame as on the wire, e.g. 0RV or 0RP3 (CR LF added unless it ends with \\n; "
                        "escapes \\r \\n \\xNN)")
    p.add_argument("--timeout", type=float, default=0.5, help="turnaround timeout in seconds (default 0.5)")
    p.add_argument("--time-scale", type=float, default=1.0,
                   help="scale of move timeouts (a simulator running faster than real time)")


def run(args: argparse.Namespace) -> int:
    from ..signals import Interrupted

    try:
        return _run(args)
    except Interrupted as exc:
        print(f"xac1 send: stopped by {exc.name}", file=sys.stderr)
        return EXIT_SIGNAL


def _run(args: argparse.Namespace) -> int:
    import serial

    from ..client import Client
    from ..console.show import answer_lines, command_bytes, error_line, port_problem, sent_lines
    from ..errors import AlarmError, ResponseTimeout, XAC1Error
    from ..exchange import answer_or_raise

    if not args.commands:
        return _usage("no command given; e.g. xac1 send --port URL 0RV 0RP3")
    for name, value in (("--timeout", args.timeout), ("--time-scale", args.time_scale)):
        if not (math.isfinite(value) and value > 0):
            return _usage(f"{name} must be a positive number, got {value}")
    try:
        frames = [command_bytes(c) for c in args.commands]
    except ValueError as exc:
        return _usage(str(exc))
    try:
        client = Client(args.port, timeout=args.timeout, time_scale=args.time_scale)
    except (serial.SerialException, OSError, ValueError) as exc:
        print(f"xac1 send: cannot open {args.port}: {port_problem(exc)}", file=sys.stderr)
        return EXIT_PORT
    with client:
        for raw in frames:
            print("\n".join(sent_lines(raw)), flush=True)
            try:
                ex = client.transact(raw)
                print("\n".join(answer_lines(ex)), flush=True)
                answer_or_raise(ex)
            except ResponseTimeout as exc:
                print(f"xac1 send: {error_line(exc)}", file=sys.stderr)
                return EXIT_TIMEOUT
            except AlarmError as exc:
                print(f"xac1 send: {error_line(exc)}", file=sys.stderr)
                return EXIT_ALARM
            except XAC1Error as exc:
                print(f"xac1 send: {error_line(exc)}", file=sys.stderr)
                return EXIT_PROTOCOL
            except (serial.SerialException, OSError) as exc:
                print(f"xac1 send: port {args.port}: {port_problem(exc)}", file=sys.stderr)
                return EXIT_PORT
    return 0
