"""``xac1 sim``: run the device simulator on a pseudo-terminal or a TCP port, controlled from stdin.

The first stdout line is where to connect: the pty's device path, or ``socket://HOST:PORT``. Then each
control command typed on stdin (``help`` lists them) prints its result. End with Ctrl-C (or SIGTERM).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from typing import Any

HELP = "run the XA-C1 device simulator on a pseudo-terminal or a TCP port"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--pty", action="store_true",
                       help="serve on a new pseudo-terminal (path printed first)")
    where.add_argument("--tcp", metavar="[HOST:]PORT",
                       help="serve pyserial socket:// clients (HOST default 127.0.0.1; one client at a time)")
    parser.add_argument("--link", metavar="PATH", help="with --pty: a symlink to the device path")
    parser.add_argument("--wire-timing", action="store_true", help="pace answers as a 9600-baud line would")
    parser.add_argument("--time-scale", type=float, default=None, metavar="F",
                        help="scale motion and turnaround (0 = instant, default 1)")
    parser.add_argument("--version", dest="fw_version", metavar="VER", help="firmware version 0RV answers "
                        "(three digits, default 100)")
    parser.add_argument("--turnaround", type=float, metavar="MS", help="answer turnaround (default 2 ms)")
    parser.add_argument("--stroke", metavar="LO:HI", help="positions a move may reach (default 0:0xFFFFFE)")
    parser.add_argument("--state", metavar="FILE", help="keep the position table in FILE across runs")
    parser.add_argument("--log", metavar="FILE", help="record every byte both ways: FILE.pcapng for "
                        "Wireshark (with verdicts), else our JSON lines recording")
    parser.add_argument("--seed", type=int, help="seed for the line faults")
    parser.add_argument("--noise", type=float, metavar="P",
                        help="corrupt each answer byte with probability P")
    parser.add_argument("--drop", type=float, metavar="P", help="drop each answer byte with probability P")
    parser.add_argument("--delay", type=float, metavar="MS", help="delay every answer by MS milliseconds")
    parser.add_argument("--estop", action="store_true", help="start with the emergency stop input on")
    parser.add_argument("--deviation", action="append", default=[], metavar="NAME",
                        help="break one stated rule on purpose (repeatable; --deviation list shows them)")
    parser.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                        help="any simulator option (the xac1sim:// query options), e.g. accept_lowercase=1")


def _options(args: argparse.Namespace) -> dict[str, Any]:
    opts: dict[str, Any] = {}
    for item in args.option:
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--option {item!r}: expected KEY=VALUE")
        opts.setdefault(key.strip(), []).append(value.strip())
    simple = {"time_scale": args.time_scale, "version": args.fw_version, "turnaround": args.turnaround,
              "stroke": args.stroke, "seed": args.seed, "noise": args.noise, "drop": args.drop,
              "delay": args.delay}
    for key, value in simple.items():
        if value is not None:
            opts[key] = [str(value)]
    if args.wire_timing:
        opts["wire_timing"] = ["1"]
    if args.deviation:
        opts["deviation"] = args.deviation
    return opts


def _tcp_address(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise ValueError(f"--tcp {text!r}: expected [HOST:]PORT with a numeric port") from None
    if not 0 <= number <= 65535:
        raise ValueError(f"--tcp {text!r}: port must be 0..65535")
    return (host.strip("[]") if sep and host else "127.0.0.1"), number


def _fail(message: str) -> int:
    print(f"xac1 sim: error: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    from ..errors import XAC1Error
    from . import control
    from .config import DEVIATIONS, config_from_options
    from .model import DeviceModel
    from .runner import serve_pty, serve_tcp
    from .state import load_state, save_state

    if args.deviation == ["list"]:
        for name, (rule, section) in DEVIATIONS.items():
            print(f"{name:28} {rule} [docs/protocol.md: {section}]")
        return 0
    if args.link and not args.pty:
        return _fail("--link goes with --pty")
    try:
        config = config_from_options(_options(args))
        address = _tcp_address(args.tcp) if args.tcp else None
        points = load_state(args.state) if args.state else {}
    except (ValueError, XAC1Error) as exc:
        return _fail(str(exc))
    model = DeviceModel(config, points)
    if args.estop:
        model.set_estop(True)

    save_errors: list[str] = []

    def on_table_change(m: DeviceModel) -> None:
        try:
            save_state(args.state, m.points)
        except OSError as exc:
            save_errors.append(str(exc))
            print(f"xac1 sim: error: cannot write the state file {args.state}: {exc}", file=sys.stderr)

    writer = None
    if args.log:
        from sniffer.io.pcapng_writer import open_recording  # a shell: the recorders live with the sniffer

        from ..chunk import Chunk
        try:
            port = f"--pty{f' --link {args.link}' if args.link else ''}" if args.pty else f"--tcp {args.tcp}"
            settings = f"time scale {config.time_scale}, wire timing {'on' if config.wire_timing else 'off'}"
            writer = open_recording(args.log, f"xac1 sim {port} ({settings})", analyze=True)
        except OSError as exc:
            return _fail(f"cannot write the log {args.log}: {exc}")

    def on_traffic(direction: str, data: bytes) -> None:
        if writer is not None:
            writer.write(Chunk(time.time(), direction, data))  # type: ignore[arg-type]

    try:
        if args.pty:
            ctx = serve_pty(model=model, link=args.link, on_traffic=on_traffic,
                            on_table_change=on_table_change if args.state else None)
        else:
            assert address is not None
            ctx = serve_tcp(model=model, host=address[0], port=address[1], on_traffic=on_traffic,
                            on_table_change=on_table_change if args.state else None)
        sim = ctx.__enter__()
    except OSError as exc:
        if writer is not None:
            writer.close()
        return _fail(f"cannot start the simulator: {exc}")
    try:
        print(sim.url, flush=True)
        print("xac1 sim: running; type 'help' for control commands, Ctrl-C to stop", file=sys.stderr)
        _control_loop(sim, control)
    except KeyboardInterrupt:
        pass
    finally:
        ctx.__exit__(None, None, None)
        if writer is not None:
            writer.close()
    return 1 if save_errors else 0


def _control_loop(sim: Any, control: Any) -> None:
    """Read control commands from stdin until EOF, then wait for Ctrl-C / SIGTERM."""
    stop = threading.Event()

    def on_term(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, on_term)
    for line in sys.stdin:
        try:
            text, _ = sim.call(lambda model, now, line=line: control.apply(model, line, now))
        except ValueError as exc:
            text = f"error: {exc}"
        if text:
            print(text, flush=True)
    if os.isatty(0):  # Ctrl-D on a terminal: the user is done
        return
    while not stop.wait(3600):  # stdin closed (run in the background): serve until a signal
        pass
