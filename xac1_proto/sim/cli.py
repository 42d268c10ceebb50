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
import contextlib
import os
import select
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from ..recording import ChunkWriter
    from ..signals import OrderlyEnd
    from .model import DeviceModel
    from .panel.server import Panel
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
                                  "help": "break one stated rule on purpose, or switch on a robustness "
                                          "fault (repeatable; --deviation list shows them)"}),
}


def _dest(flag: str) -> str:
    return "opt_" + flag.lstrip("-").replace("-", "_")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group()  # one is needed, but not by --deviation list
    where.add_argument("--pty", action="store_true",
                       help="serve on a new pseudo-terminal (path printed first)")
    where.add_argument("--tcp", metavar="[HOST:]PORT",
                       help="serve pyserial socket:// clients (HOST default 127.0.0.1; one client at a time)")
    parser.add_argument("--link", metavar="PATH", help="with --pty: a symlink to the device path")
    parser.add_argument("--panel", metavar="[HOST:]PORT",
                        help="also serve the front panel, a web page (HOST default 127.0.0.1; needs the "
                             "panel extra: pip install 'xac1-proto[panel]')")
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


def _address(text: str, flag: str) -> tuple[str, int]:
    """``[HOST:]PORT`` (HOST default 127.0.0.1; ``[::1]:PORT`` for IPv6) of ``--tcp`` or ``--panel``."""
    host, sep, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise ValueError(f"{flag} {text!r}: expected [HOST:]PORT with a numeric port") from None
    if not 0 <= number <= 65535:
        raise ValueError(f"{flag} {text!r}: port must be 0..65535")
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

    if args.opt_deviation == ["list"]:  # a list needs no transport, nor anything else
        from .config import deviation_listing

        for name, what in deviation_listing():
            print(f"{name:28} {what}")
        return EXIT_OK
    problem = _usage_problem(args)
    if problem:
        return _fail(problem)
    what = "stopping the simulator" + (" and writing the state file" if args.state else "")
    with OrderlyEnd("xac1 sim", what) as end:
        try:
            return _run(args, end)
        except Interrupted as exc:
            if not end.early:
                raise
            print(f"xac1 sim: stopped by {exc.name} before it was serving", file=sys.stderr)
            return EXIT_EARLY


def _usage_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with the options' combination, or None."""
    if not (args.pty or args.tcp):
        return "one of the arguments --pty --tcp is required"
    if args.link and not args.pty:
        return "--link goes with --pty"
    if args.replay is None and (args.replay_strict or args.replay_format != "auto" or args.replay_host_is):
        return "--replay-strict, --replay-format and --replay-host-is go with --replay CAPTURE"
    return None


class Run:
    """What one ``xac1 sim`` run holds beside the simulator: the model it serves, the ``--log`` writer,
    the ``--state`` file and the front panel. Built from the options, each checked before anything
    starts (``ValueError`` or ``XAC1Error`` saying what is wrong); ``close`` ends them in order."""

    def __init__(self, args: argparse.Namespace) -> None:
        from .config import config_from_options
        from .model import DeviceModel
        from .replaying import ReplayingDevice, load_script
        from .state import load_state

        self.args = args
        self.config = config_from_options(_options(args))
        self.address = _address(args.tcp, "--tcp") if args.tcp else None
        panel_at = _address(args.panel, "--panel") if args.panel else None
        if args.state:  # a regular file (or a link to one), checked before anything starts
            from ..output_file import check_output

            check_output(args.state, "--state")
        points = load_state(args.state) if args.state else {}
        self.writer: ChunkWriter | None = None
        self.save_errors: list[str] = []
        if args.replay is not None:
            script = load_script(args.replay, args.replay_format, args.replay_host_is)
            self.model: DeviceModel = ReplayingDevice(
                script, self.config, strict=args.replay_strict, points=points,
                on_note=lambda note: _say_replay(note, self.writer))
            print(f"xac1 sim: replaying {len(script)} captured host lines of {', '.join(args.replay)}"
                  f"{' (strict)' if args.replay_strict else ''}", file=sys.stderr, flush=True)
        else:
            self.model = DeviceModel(self.config, points)
        if args.estop:
            self.model.set_estop(True)
        self.panel = _open_panel(*panel_at) if panel_at else None
        if args.log is not None:
            port = f"--pty{f' --link {args.link}' if args.link else ''}" if args.pty else f"--tcp {args.tcp}"
            settings = (f"time scale {self.config.time_scale}, "
                        f"wire timing {'on' if self.config.wire_timing else 'off'}")
            try:
                self.writer = open_log(args.log, f"xac1 sim {port} ({settings})")
            except OSError as exc:
                self.close_panel()
                raise ValueError(f"cannot write the log {args.log}: {exc.strerror or exc}") from None

    def on_traffic(self, direction: str, data: bytes) -> None:
        """The simulator's bytes both ways (its thread): to the log and the panel."""
        if self.writer is not None:
            from ..chunk import Chunk

            try:
                self.writer.write(Chunk(time.time(), direction, data))  # type: ignore[arg-type]
            except OSError as exc:
                raise RuntimeError(f"cannot write the log {self.args.log}: {exc.strerror or exc}") from None
        if self.panel is not None:
            self.panel.tap(direction, data)

    def save(self, model: DeviceModel) -> None:
        """The position table to ``--state`` (on every change, and at the end)."""
        from .state import save_state

        try:
            save_state(self.args.state, model.points)
        except (OSError, ValueError) as exc:  # ValueError: OutputFileError, it is no longer a file
            self.save_errors.append(str(exc))
            print(f"xac1 sim: error: cannot write the state file {self.args.state}: {exc}", file=sys.stderr)

    def serve(self) -> contextlib.AbstractContextManager[RunningSim]:
        """The simulator on its pty or TCP port (OSError when it cannot start)."""
        from .runner import serve_pty, serve_tcp

        hooks: dict[str, Any] = {"model": self.model, "on_traffic": self.on_traffic,
                                 "on_table_change": self.save if self.args.state else None}
        if self.address is None:
            return serve_pty(link=self.args.link, **hooks)
        return serve_tcp(host=self.address[0], port=self.address[1], **hooks)

    def close_panel(self) -> None:
        if self.panel is not None:
            self.panel.close()
            if self.panel.error is not None:  # the page went away before the simulator: said, not fatal
                print(f"xac1 sim: error: the front panel stopped: {self.panel.error!r}", file=sys.stderr)

    def close(self, died: bool) -> bool:
        """End the panel, save the table (unless the simulator died) and close the log; False when
        something could not be written."""
        self.close_panel()
        if self.args.state and not died:
            self.save(self.model)  # the last word: the table as the run left it
        if self.writer is not None:
            try:
                self.writer.close()
            except OSError as exc:
                print(f"xac1 sim: error: cannot write the log {self.args.log}: {exc}", file=sys.stderr)
                return False
        return not self.save_errors


def _open_panel(host: str, port: int) -> Panel:
    """The front panel's server, bound (``ValueError`` naming the address when it cannot be, or when
    the panel extra is not installed)."""
    try:
        from .panel.server import Panel, PanelError
    except ImportError as exc:
        raise ValueError(f"--panel needs the panel extra (pip install 'xac1-proto[panel]'): {exc}") from None
    try:
        return Panel(host, port)
    except PanelError as exc:
        raise ValueError(str(exc)) from None


def _run(args: argparse.Namespace, end: OrderlyEnd) -> int:
    from ..errors import XAC1Error
    from .control import ControlChannel

    try:
        parts = Run(args)
    except (ValueError, XAC1Error) as exc:
        return _fail(str(exc))
    try:
        ctx = parts.serve()
        sim = ctx.__enter__()
    except OSError as exc:
        parts.close(died=True)
        return _fail(f"cannot start the simulator: {exc}")
    died = False
    try:
        end.begin()  # serving from here: a signal now ends it in order
        control = ControlChannel(sim, parts.panel.fact if parts.panel else None)
        print(sim.url, flush=True)
        if parts.panel is not None:
            parts.panel.start(sim, control)
            print(f"xac1 sim: front panel at {parts.panel.url}", file=sys.stderr, flush=True)
        print("xac1 sim: running; type 'help' for control commands, Ctrl-C to stop", file=sys.stderr,
              flush=True)
        died = _control_loop(sim, end, control)
    finally:
        end.ending()
        parts.close_panel()
        try:
            ctx.__exit__(None, None, None)
        except RuntimeError:
            died = True  # said below
        if died:
            print(f"xac1 sim: error: the simulator stopped: {_reason(sim.server.error)}", file=sys.stderr)
        written = parts.close(died)
    return EXIT_FAILED if died or not written else EXIT_OK


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


def _control_loop(sim: RunningSim, end: OrderlyEnd, control: Callable[[str], str], stdin_fd: int = 0) -> bool:
    """Run control commands from ``stdin_fd`` through ``control`` until a signal (``end.stop``), the end
    of stdin on a terminal, or the simulator's loop dies; True in that last case."""
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
            try:
                text = control(raw.decode("utf-8", "replace"))
            except ValueError as exc:
                text = f"error: {exc}"
            if text:
                print(text, flush=True)
    return sim.failed.is_set()
