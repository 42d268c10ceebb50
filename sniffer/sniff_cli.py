"""``xac1 sniff``: watch a live line through two receive-only taps (a Y-cable) and explain every exchange."""

from __future__ import annotations

import argparse

HELP = "watch live traffic through two receive-only taps (host TX, device TX) and decode it"


def add_common_output(parser: argparse.ArgumentParser) -> None:
    """Output and analysis options shared with ``xac1 proxy``."""
    parser.add_argument("--format", choices=("text", "jsonl"), default="text",
                        help="text: a colour line per frame (default); jsonl: one JSON object a line")
    parser.add_argument("--record", metavar="FILE",
                        help="also write every chunk to FILE: FILE.pcapng for Wireshark (verdicts as packet "
                             "comments), else our JSON lines recording; both read by xac1 decode")
    parser.add_argument("--timeout", type=float, default=1.0, metavar="S",
                        help="no-answer timeout in seconds after a command's last byte; moves get their "
                             "estimated time doubled on top (default 1.0)")
    parser.add_argument("--storm-limit", type=int, default=5, metavar="N",
                        help="communication-error answers in a row after which a command is "
                             "comm-error-storm (default 5)")
    parser.add_argument("--color", action=argparse.BooleanOptionalAction, default=None,
                        help="colour in the text view (default: when the output is a terminal)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host-tap", required=True, metavar="PORT",
                        help="serial port wired to the host's TX (what the host sends)")
    parser.add_argument("--device-tap", required=True, metavar="PORT",
                        help="serial port wired to the controller's TX (what the controller answers)")
    parser.add_argument("--baud", type=int, default=9600, help="line speed of the taps (default 9600)")
    parser.add_argument("--reconnect", action="store_true",
                        help="when a tap goes away, wait for it to come back instead of stopping")
    add_common_output(parser)


def make_session(args: argparse.Namespace, source: str):  # -> live.Session (import kept lazy)
    import sys

    from .analyzer import Analyzer
    from .io.pcapng_writer import open_recording
    from .live import Session
    from .view import make_view

    if args.timeout <= 0:
        raise ValueError(f"--timeout must be positive, got {args.timeout}")
    if args.storm_limit < 1:
        raise ValueError(f"--storm-limit must be at least 1, got {args.storm_limit}")
    recorder = None
    if args.record:
        try:
            settings = (f"baud {getattr(args, 'baud', 9600)}, timeout {args.timeout} s, "
                        f"storm limit {args.storm_limit}")
            recorder = open_recording(args.record, f"{source} ({settings})",
                                      fmt=getattr(args, "record_format", None))  # extcap: a FIFO
        except OSError as exc:
            raise ValueError(f"cannot write the recording {args.record}: {exc.strerror}") from None
    analyzer = Analyzer(no_answer_timeout=args.timeout, storm_limit=args.storm_limit)
    return Session(analyzer, make_view(args.format, sys.stdout, args.color), recorder)


def stop_on_signals():  # -> threading.Event (import kept lazy)
    """An event set by Ctrl-C (SIGINT) or SIGTERM: the loop then ends between two polls, so the last
    chunk is recorded and analysed whole before the summary."""
    import signal
    import threading

    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    return stop


def run(args: argparse.Namespace) -> int:
    import sys
    import threading

    from .live import Clock, sniff
    from .taps import PortGone

    try:
        session = make_session(args, f"xac1 sniff --host-tap {args.host_tap} --device-tap {args.device_tap}")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    clock = Clock()
    started = threading.Event()
    stop = stop_on_signals()
    code = 0
    try:
        code = sniff({"host": args.host_tap, "device": args.device_tap}, session, clock, baud=args.baud,
                     reconnect=args.reconnect, stop=stop, started=started, err=sys.stderr)
    except PortGone as exc:  # a tap that cannot be opened at the start
        print(f"error: {exc}", file=sys.stderr)
        code = 1
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        code = 2
    except KeyboardInterrupt:
        code = 0
    finally:
        session.close(clock.now(), summary=started.is_set())
    return code
