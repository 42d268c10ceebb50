"""``xac1 sim``: run the device simulator on a pseudo-terminal or a TCP port, controlled from stdin.

The first stdout line is where to connect: the pty's device path, or ``socket://HOST:PORT``. Then each
control command typed on stdin (``help`` lists them, ``control.CONTROLS`` is their one table) prints its
result. The simulator options are one table too (``FLAGS``: flag -> simulator option of
``config.OPTIONS``), so the flags and the ``xac1sim://`` query string check values in one place.

It ends in order (``xac1_proto.signals``) on SIGINT, SIGTERM or SIGHUP, or at the end of stdin on a
terminal (Ctrl-D): the loop is stopped, the state file written, the log closed. When stdin is not a
terminal, its end does not stop the simulator (it serves until a signal). If the simulator's loop dies
(a log that cannot be written, a bug), it says so at once and ends with exit 1.

Exit status: 0 ended in order; 1 the simulator failed (its loop died, the state file could not be
written); 2 bad options or a signal before it was serving.
"""

from __future__ import annotations

import argparse
import os
import select
import sys
import time
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from ..recording import ChunkWriter
    from ..signals import OrderlyEnd
    from .model import DeviceModel
    from .outbox import Output
    from .runner import RunningSim

HELP = "run the XA-C1 device simulator on a pseudo-terminal or a TCP port"

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
POLL_S = 0.1  # how often the control loop looks at the simulator's health and the stop event

# The one table of simulator flags: flag -> (simulator option it sets, argparse keywords). The values
# are checked by ``config.config_from_options``, the same code that checks an ``xac1sim://`` URL.
FLAGS: Final[dict[str, tuple[str, dict[str, Any]]]] = {
    "--time-scale": ("time_scale", {"metavar": "F", "help": "scale motion and turnaround "
                                    "(0 = instant, default 1, at most 1000)"}),
    "--wire-timing": ("wire_timing", {"action": "store_true",
                                      "help": "pace answers as a 9600-baud line would"}),
    "--version": ("version", {"metavar": "VER", "help": "firmware version 0RV answers "
                              "(three digits, default 100)"}),
    "--turnaround": ("turnaround", {"metavar": "MS", "help": "answer turnaround (default 2 ms, "
                                    "at most 60000)"}),
    "--stroke": ("stroke", {"metavar": "LO:HI", "help": "positions a move may reach (default 0:0xFFFFFE)"}),
    "--seed": ("seed", {"metavar": "N", "help": "seed for the line faults"}),
    "--noise": ("noise", {"metavar": "P", "help": "corrupt each answer byte with probability P"}),
    "--drop": ("drop", {"metavar": "P", "help": "drop each answer byte with probability P"}),
    "--delay": ("delay", {"metavar": "MS", "help": "delay every answer by MS milliseconds (at most 60000)"}),
    "--deviation": ("deviation", {"action": "append", "metavar": "NAME",
                                  "help": "break one stated rule on purpose (repeatable; "
                                          "--deviation list shows them)"}),
}


def _dest(flag: str) -> str:
    return "opt_" + flag.lstrip("-").replace("-", "_")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--pty", action="store_true",
                       help="serve on a new pseudo-terminal (path printed first)")
    where.add_argument("--tcp", metavar="[HOST:]PORT",
                       help="serve pyserial socket:// clients (HOST default 127.0.0.1; one client at a time)")
    parser.add_argument("--link", metavar="PATH", help="with --pty: a symlink to the device path")
    for flag, (_, kwargs) in FLAGS.items():
        parser.add_argument(flag, dest=_dest(flag), **kwargs)
    parser.add_argument("--state", metavar="FILE", help="keep the position table in FILE across runs")
    parser.add_argument("--log", metavar="FILE", help="record every byte both ways: FILE.pcapng for "
                        "Wireshark (with verdicts), else our JSON lines recording")
    parser.add_argument("--estop", action="store_true", help="start with the emergency stop input on")
    parser.add_argument("--replay", action="append", metavar="CAPTURE", default=None,
                        help="answer as the captured device did: any capture xac1 decode reads (give it "
                             "twice for formats with one file per direction); lines the capture does not "
                             "hold next are answered by the model")
    parser.add_argument("--replay-strict", action="store_true",
                        help="with --replay: a line the capture does not hold next gets no answer")
    parser.add_argument("--replay-format", metavar="FORMAT", default="auto",
                        help="with --replay: the capture's format (default: sniffed, as xac1 decode)")
    parser.add_argument("--replay-host-is", metavar="SIDE", default=None,
                        help="with --replay: which side of the capture is the host (as decode's --host-is)")
    parser.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                        help="any simulator option (the xac1sim:// query options), e.g. accept_lowercase=1")


def _options(args: argparse.Namespace) -> dict[str, list[str]]:
    """The simulator options the command line gives (``--option`` first, the named flags over it)."""
    opts: dict[str, list[str]] = {}
    for item in args.option:
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--option {item!r}: expected KEY=VALUE")
        opts.setdefault(key.strip(), []).append(value.strip())
    for flag, (option, _) in FLAGS.items():
        value = getattr(args, _dest(flag))
        if value in (None, False):
            continue
        if value is True:
            opts[option] = ["1"]
        elif isinstance(value, list):
            opts[option] = [str(v) for v in value]
        else:
            opts[option] = [str(value)]
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
    return EXIT_USAGE


def open_log(path: str, source: str) -> ChunkWriter:
    """The writer for ``--log FILE``, by suffix (``.pcapng`` for Wireshark, with verdicts, where the
    sniffer is installed; else our JSON lines recording). OSError when it cannot be written."""
    from ..recording import open_recording

    return open_recording(path, source, analyze=True)


def run(args: argparse.Namespace) -> int:
    from ..signals import EXIT_EARLY, Interrupted, OrderlyEnd

    what = "stopping the simulator" + (" and writing the state file" if args.state else "")
    with OrderlyEnd("xac1 sim", what) as end:
        try:
            return _run(args, end)
        except Interrupted as exc:
            if not end.early:
                raise
            print(f"xac1 sim: stopped by {exc.name} before it was serving", file=sys.stderr)
            return EXIT_EARLY


def _run(args: argparse.Namespace, end: OrderlyEnd) -> int:
    from ..chunk import Chunk
    from ..errors import XAC1Error
    from ..output_file import check_output
    from .config import DEVIATIONS, config_from_options
    from .model import DeviceModel
    from .replaying import ReplayingDevice, load_script
    from .runner import serve_pty, serve_tcp
    from .state import load_state, save_state

    if args.opt_deviation == ["list"]:
        for name, (rule, section) in DEVIATIONS.items():
            print(f"{name:28} {rule} [docs/protocol.md: {section}]")
        return EXIT_OK
    if args.link and not args.pty:
        return _fail("--link goes with --pty")
    replaying = args.replay is not None
    if not replaying and (args.replay_strict or args.replay_format != "auto" or args.replay_host_is):
        return _fail("--replay-strict, --replay-format and --replay-host-is go with --replay CAPTURE")
    try:
        config = config_from_options(_options(args))
        address = _tcp_address(args.tcp) if args.tcp else None
        if args.state:  # a regular file (or a link to one), checked before anything starts
            check_output(args.state, "--state")
        points = load_state(args.state) if args.state else {}
        script = load_script(args.replay, args.replay_format, args.replay_host_is) if replaying else None
    except (ValueError, XAC1Error) as exc:
        return _fail(str(exc))
    if script is not None:
        model: DeviceModel = ReplayingDevice(script, config, strict=args.replay_strict, points=points,
                                             on_note=lambda note: _say_replay(note, writer))
        print(f"xac1 sim: replaying {len(script)} captured host lines of {', '.join(args.replay)}"
              f"{' (strict)' if args.replay_strict else ''}", file=sys.stderr, flush=True)
    else:
        model = DeviceModel(config, points)
    if args.estop:
        model.set_estop(True)

    save_errors: list[str] = []

    def save(m: DeviceModel) -> None:
        try:
            save_state(args.state, m.points)
        except (OSError, ValueError) as exc:  # ValueError: OutputFileError, it is no longer a file
            save_errors.append(str(exc))
            print(f"xac1 sim: error: cannot write the state file {args.state}: {exc}", file=sys.stderr)

    writer = None
    if args.log is not None:
        try:
            port = f"--pty{f' --link {args.link}' if args.link else ''}" if args.pty else f"--tcp {args.tcp}"
            settings = f"time scale {config.time_scale}, wire timing {'on' if config.wire_timing else 'off'}"
            writer = open_log(args.log, f"xac1 sim {port} ({settings})")
        except OSError as exc:
            return _fail(f"cannot write the log {args.log}: {exc.strerror or exc}")

    def on_traffic(direction: str, data: bytes) -> None:
        if writer is not None:
            try:
                writer.write(Chunk(time.time(), direction, data))  # type: ignore[arg-type]
            except OSError as exc:
                raise RuntimeError(f"cannot write the log {args.log}: {exc.strerror or exc}") from None

    try:
        if args.pty:
            ctx = serve_pty(model=model, link=args.link, on_traffic=on_traffic,
                            on_table_change=save if args.state else None)
        else:
            assert address is not None
            ctx = serve_tcp(model=model, host=address[0], port=address[1], on_traffic=on_traffic,
                            on_table_change=save if args.state else None)
        sim = ctx.__enter__()
    except OSError as exc:
        if writer is not None:
            writer.close()
        return _fail(f"cannot start the simulator: {exc}")
    died = False
    try:
        end.begin()  # serving from here: a signal now ends it in order
        print(sim.url, flush=True)
        print("xac1 sim: running; type 'help' for control commands, Ctrl-C to stop", file=sys.stderr,
              flush=True)
        died = _control_loop(sim, end)
    finally:
        end.ending()
        try:
            ctx.__exit__(None, None, None)
        except RuntimeError:
            died = True  # said below
        if died:
            print(f"xac1 sim: error: the simulator stopped: {_reason(sim.server.error)}", file=sys.stderr)
        if args.state and not died:
            save(model)  # the last word: the table as the run left it
        if writer is not None:
            try:
                writer.close()
            except OSError as exc:
                print(f"xac1 sim: error: cannot write the log {args.log}: {exc}", file=sys.stderr)
                died = True
    return EXIT_FAILED if died or save_errors else EXIT_OK


def _say_replay(note: str, log: ChunkWriter | None) -> None:
    """A line the capture does not hold next (from the simulator's loop): said on stderr at once, and in
    the ``--log`` recording (JSON lines: a note line; pcapng: a packet comment)."""
    print(f"xac1 sim: replay: {note}", file=sys.stderr, flush=True)
    take_note = getattr(log, "note", None)
    if take_note is not None:
        take_note(f"replay: {note}")


def _reason(error: BaseException | None) -> str:
    if error is None:
        return "its loop did not stop in time"
    if isinstance(error, RuntimeError) and error.args:
        return str(error)
    return repr(error)


def _control_loop(sim: RunningSim, end: OrderlyEnd, stdin_fd: int = 0) -> bool:
    """Run control commands from ``stdin_fd`` until a signal (``end.stop``), the end of stdin on a
    terminal, or the simulator's loop dies; True in that last case."""
    from . import control

    pending = b""
    stdin_open = True
    while not end.stop.is_set():
        if sim.failed.is_set():
            return True
        if not stdin_open:
            end.stop.wait(POLL_S)
            continue
        try:
            ready = select.select([stdin_fd], [], [], POLL_S)[0]
        except (OSError, ValueError):  # no stdin at all
            stdin_open = False
            continue
        if not ready:
            continue
        try:
            data = os.read(stdin_fd, 4096)
        except (BlockingIOError, InterruptedError):
            continue
        except OSError:
            data = b""
        if not data:
            stdin_open = False
            if os.isatty(stdin_fd):  # Ctrl-D on a terminal: the user is done
                return False
            continue  # stdin closed (run in the background): serve until a signal
        pending += data
        *lines, pending = pending.split(b"\n")
        for raw in lines:
            line = raw.decode("utf-8", "replace")

            def apply(model: DeviceModel, now: float, line: str = line) -> tuple[str, list[Output]]:
                return control.apply(model, line, now)

            try:
                text, _ = sim.call(apply)
            except ValueError as exc:
                text = f"error: {exc}"
            if text:
                print(text, flush=True)
    return sim.failed.is_set()
