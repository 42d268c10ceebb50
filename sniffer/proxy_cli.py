"""``xac1 proxy``: stand between host software and the controller, forward every byte, decode on the way."""

from __future__ import annotations

import argparse

from xac1_proto import spec

from .sniff_cli import add_common_output

HELP = "forward bytes between host software (pty or TCP) and the controller, decoding them on the way"


def _tcp_address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected [HOST:]PORT, got {text!r}") from None
    if not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"port must be 0-65535, got {number}")
    return (host or "127.0.0.1", number)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--device", required=True, metavar="PORT",
                        help="the controller's serial port (a path, or a pyserial URL such as socket://H:P)")
    side = parser.add_mutually_exclusive_group(required=True)
    side.add_argument("--pty", action="store_true", help="offer the host a pseudo-terminal")
    side.add_argument("--tcp", type=_tcp_address, metavar="[HOST:]PORT",
                      help="offer the host a TCP port (default host 127.0.0.1)")
    parser.add_argument("--link", metavar="PATH", help="with --pty: a symlink to the pty at PATH")
    parser.add_argument("--baud", type=int, default=spec.BAUD, help=f"line speed (default {spec.BAUD})")
    parser.add_argument("--reconnect", action="store_true",
                        help="when the device port goes away, wait for it to come back instead of stopping")
    add_common_output(parser)


def run(args: argparse.Namespace) -> int:
    import sys

    from xac1_proto.signals import EXIT_EARLY, Interrupted, OrderlyEnd

    from .live import Clock
    from .proxy import Proxy, PtyHost, TcpHost
    from .sniff_cli import make_session
    from .taps import PortGone

    if args.link and not args.pty:
        print("xac1 proxy: error: --link goes with --pty", file=sys.stderr)
        return 2
    with OrderlyEnd("xac1 proxy", "stopping: the summary follows") as end:
        try:
            host_side = "--pty" + (f" --link {args.link}" if args.link else "") if args.pty else \
                f"--tcp {args.tcp[0]}:{args.tcp[1]}"
            session = make_session(args, f"xac1 proxy --device {args.device} {host_side}", "xac1 proxy")
        except ValueError as exc:
            print(f"xac1 proxy: error: {exc}", file=sys.stderr)
            return 2
        except Interrupted as exc:
            print(f"xac1 proxy: stopped by {exc.name} before it was forwarding", file=sys.stderr)
            return EXIT_EARLY
        clock = Clock()
        proxy = None
        code = 0
        try:
            try:
                host = PtyHost(args.link, args.baud) if args.pty else TcpHost(*args.tcp)
            except OSError as exc:
                print(f"xac1 proxy: error: cannot offer the host side: {exc}", file=sys.stderr)
                return 1
            try:
                proxy = Proxy(host, args.device, session, clock, baud=args.baud,
                              reconnect=args.reconnect, err=sys.stderr)
            except PortGone as exc:
                host.close()
                print(f"xac1 proxy: error: {exc}", file=sys.stderr)
                return 1
            where = (f"pty {host.path}" + (f" (link {args.link})" if args.link else "")
                     if isinstance(host, PtyHost) else f"tcp {host.address[0]}:{host.address[1]}")
            end.begin()
            print(f"xac1 proxy: host side on {where}; device {args.device}; Ctrl-C to stop", file=sys.stderr,
                  flush=True)
            code = proxy.run(end.stop)
        except Interrupted as exc:  # only before it was forwarding (after, a signal sets end.stop)
            print(f"xac1 proxy: stopped by {exc.name} before it was forwarding", file=sys.stderr)
            code = EXIT_EARLY
        finally:
            end.ending()
            if proxy is not None:
                proxy.close()
                proxy.drain()  # what was forwarded is decoded and recorded too
            session.close(clock.now(), summary=proxy is not None and not end.early)
        return code
