"""``xac1 sniff``: watch a live line through two receive-only taps (a Y-cable) and explain every exchange."""

from __future__ import annotations

import argparse

from xac1_proto import rules, spec
from xac1_proto.speed_option import add_speed_table_option, speeds_of

HELP = "watch live traffic through two receive-only taps (host TX, device TX) and decode it"


def add_common_output(parser: argparse.ArgumentParser) -> None:
    """Output and analysis options shared with ``xac1 proxy``."""
    parser.add_argument("--format", choices=("text", "jsonl"), default="text",
                        help="text: a colour line per frame (default); jsonl: one JSON object a line")
    parser.add_argument("--record", metavar="FILE",
                        help="also write every chunk to FILE: FILE.pcapng for Wireshark (verdicts as packet "
                             "comments), else our JSON lines recording; both read by xac1 decode")
    parser.add_argument("--timeout", type=float, default=spec.NO_ANSWER_TIMEOUT_S, metavar="S",
                        help="no-answer timeout in seconds after a command's last byte; moves get their "
                             f"estimated time doubled on top (default {spec.NO_ANSWER_TIMEOUT_S})")
    parser.add_argument("--storm-limit", type=int, default=spec.STORM_LIMIT, metavar="N",
                        help="communication-error answers in a row after which a command is "
                             f"comm-error-storm (default {spec.STORM_LIMIT})")
    parser.add_argument("--readings", choices=rules.READINGS, default=rules.DEFAULT_READINGS,
                        help=rules.READINGS_HELP)
    add_speed_table_option(parser)
    parser.add_argument("--color", action=argparse.BooleanOptionalAction, default=None,
                        help="colour in the text view (default: when the output is a terminal)")
    parser.add_argument("--report", metavar="FILE",
                        help="write an HTML session report to FILE when the run ends (needs the "
                             "'report' extra)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host-tap", required=True, metavar="PORT",
                        help="serial port wired to the host's TX (what the host sends)")
    parser.add_argument("--device-tap", required=True, metavar="PORT",
                        help="serial port wired to the controller's TX (what the controller answers)")
    parser.add_argument("--baud", type=int, default=spec.BAUD,
                        help=f"line speed of the taps (default {spec.BAUD})")
    parser.add_argument("--reconnect", action="store_true",
                        help="when a tap goes away, wait for it to come back instead of stopping")
    add_common_output(parser)


def open_recording(path: str, source: str, fmt: str | None = None):  # -> Recorder (import kept lazy)
    """The recorder for ``--record FILE`` (pcapng by the suffix or ``fmt``, else our JSON lines
    recording); ValueError with a message for people when it cannot be written."""
    from .io import pcapng_writer

    try:
        return pcapng_writer.open_recording(path, source, fmt=fmt)
    except OSError as exc:
        raise ValueError(f"cannot write the recording {path}: {exc.strerror or exc}") from None


def make_session(args: argparse.Namespace, source: str,
                 program: str = "xac1 sniff"):  # -> live.Session (import kept lazy)
    import sys

    from .analyzer import Analyzer
    from .live import Session
    from .view import make_view

    if not args.timeout > 0 or args.timeout == float("inf"):
        raise ValueError(f"--timeout must be a positive number of seconds, got {args.timeout}")
    if args.storm_limit < 1:
        raise ValueError(f"--storm-limit must be at least 1, got {args.storm_limit}")
    report = None
    if args.report is not None:
        from .report import SessionReport
        report = SessionReport.open(args.report, [(source, "live")], args.timeout)  # ReportError: ValueError
    recorder = None
    if args.record is not None:
        settings = (f"baud {getattr(args, 'baud', spec.BAUD)}, timeout {args.timeout} s, "
                    f"storm limit {args.storm_limit}")
        recorder = open_recording(args.record, f"{source} ({settings})",
                                  fmt=getattr(args, "record_format", None))  # extcap: a FIFO
    analyzer = Analyzer(no_answer_timeout=args.timeout, storm_limit=args.storm_limit,
                        readings=args.readings, speeds=speeds_of(args))
    if report is not None:
        from .report.live import ReportingSession
        return ReportingSession(analyzer, make_view(args.format, sys.stdout, args.color), recorder, report,
                                output=sys.stdout, err=sys.stderr, program=program)
    return Session(analyzer, make_view(args.format, sys.stdout, args.color), recorder, output=sys.stdout,
                   err=sys.stderr, program=program)


def _started_event(end):  # (end: OrderlyEnd) -> threading.Event (imports kept lazy)
    """The ``started`` event ``live.sniff`` sets once both taps are open: from then on a signal ends the
    run in order (``OrderlyEnd.begin``) instead of aborting the start."""
    import threading

    class Started(threading.Event):
        def set(self) -> None:
            end.begin()
            super().set()

    return Started()


def _same_port(a: str, b: str) -> bool:
    """Do two port names name one port (a path through its links; a URL as written)?"""
    import os

    return a == b or ("://" not in a and "://" not in b and os.path.realpath(a) == os.path.realpath(b))


def run(args: argparse.Namespace) -> int:
    import sys

    from xac1_proto.signals import EXIT_EARLY, Interrupted, OrderlyEnd

    from .live import Clock, sniff
    from .taps import PortGone

    if _same_port(args.host_tap, args.device_tap):
        print(f"error: --host-tap and --device-tap name the same port ({args.device_tap}): each direction "
              f"needs its own tap (docs/watching.md)", file=sys.stderr)
        return 2
    with OrderlyEnd("xac1 sniff", "stopping: the summary follows") as end:
        try:
            session = make_session(args, f"xac1 sniff --host-tap {args.host_tap} "
                                         f"--device-tap {args.device_tap}")
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        except Interrupted as exc:
            print(f"xac1 sniff: stopped by {exc.name} before the taps were open", file=sys.stderr)
            return EXIT_EARLY
        clock = Clock()
        started = _started_event(end)
        code = 0
        try:
            code = sniff({"host": args.host_tap, "device": args.device_tap}, session, clock,
                         baud=args.baud, reconnect=args.reconnect, stop=end.stop,
                         started=started, err=sys.stderr)
        except PortGone as exc:  # a tap that cannot be opened at the start
            print(f"error: {exc}", file=sys.stderr)
            code = 1
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            code = 2
        except Interrupted as exc:  # only before the taps were open (after, a signal sets end.stop)
            print(f"xac1 sniff: stopped by {exc.name} before the taps were open", file=sys.stderr)
            code = EXIT_EARLY
        finally:
            end.ending()
            session.close(clock.now(), summary=started.is_set())
        return code
