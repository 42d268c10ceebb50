"""The ``xac1`` console script: one subcommand a module, imported only when it runs.

Each subcommand module has ``HELP`` (one line; ``COMMANDS`` repeats it so that ``xac1 --help`` imports
nothing, and a test checks the two agree), ``add_arguments(parser)`` and ``run(args) -> int``.

Shell completion is argcomplete's: the shell's hook (``register-python-argcomplete xac1``) runs ``xac1``
with ``_ARGCOMPLETE`` and ``COMP_LINE`` set; only then is argcomplete imported, the parser built for the
words typed so far (the subcommand's module imported only once its name is complete) and the
completions written for the shell, and the process ends there.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from dataclasses import dataclass
from typing import Final

from .. import __version__


@dataclass(frozen=True)
class Subcommand:
    """Where a subcommand lives and its one-line help (the module's ``HELP``, checked by a test)."""

    module: str
    help: str


# name -> subcommand; ``xac1 --help`` is built from this table alone, importing nothing.
COMMANDS: Final[dict[str, Subcommand]] = {
    "parse": Subcommand("xac1_proto.cli.parse_cmd",
                        "decode one frame (text with \\r\\n escapes, or hex) and explain any error"),
    "sim": Subcommand("xac1_proto.sim.cli",
                      "run the XA-C1 device simulator on a pseudo-terminal or a TCP port"),
    "send": Subcommand("xac1_proto.cli.send_cmd",
                       "send raw commands (e.g. 0RV 0RP3) to a controller and show the answers decoded"),
    "console": Subcommand("xac1_proto.cli.console_cmd",
                          "interactive console: named commands (read 3, home, go ...), raw frames (!0RV), "
                          "history, help"),
    "ports": Subcommand("xac1_proto.cli.ports_cmd",
                        "list the serial ports (USB ids, serial numbers) and, with --probe, which answer as "
                        "an XA-C1"),
    "conformance": Subcommand("conformance.cli",
                              "run the conformance suite against a controller (default: the built-in "
                              "simulator) and report"),
    "history": Subcommand("xac1_proto.history.cli",
                          "the acceptance history: list, show and compare recorded runs, per unit and "
                          "firmware; sync the spool"),
    "sniff": Subcommand("sniffer.sniff_cli",
                        "watch live traffic through two receive-only taps (host TX, device TX) and "
                        "decode it"),
    "proxy": Subcommand("sniffer.proxy_cli",
                        "forward bytes between host software (pty or TCP) and the controller, decoding them "
                        "on the way"),
    "decode": Subcommand("sniffer.decode_cli",
                         "decode a capture file (socat, spy://, interceptty, jpnevulator, Saleae, sigrok, "
                         "pcap, raw, jsonl)"),
    "replay": Subcommand("sniffer.replay_cli",
                         "play a capture's host side against a controller (or the simulator) and show "
                         "where the answers differ"),
    "fuzz": Subcommand("xac1_proto.cli.fuzz_cmd",
                        "send hostile lines (never a move) to a controller (default: the simulator) and "
                        "report what it does not stand up to"),
    "wireshark": Subcommand("sniffer.wireshark.wireshark_cmd",
                            "install the XA-C1 Wireshark dissector and extcap (install [--uninstall]), or "
                            "show its folders (path)"),
    "sigrok": Subcommand("sniffer.sigrok.sigrok_cmd",
                         "install the XA-C1 sigrok decoder for PulseView and sigrok-cli (install "
                         "[--uninstall]), or show its folder (path)"),
    "extcap": Subcommand("sniffer.wireshark.extcap_cmd",
                         "Wireshark extcap interface (XA-C1 tap, XA-C1 proxy); Wireshark runs it"),
}


def _build(argv: list[str]) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="xac1",
        description="Protocol analyzer and conformance kit for the SUS XA-C1 actuator controller.",
    )
    parser.add_argument("--version", action="version", version=f"xac1 {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    wanted = next((a for a in argv if not a.startswith("-")), None)
    for name, command in COMMANDS.items():
        p = sub.add_parser(name, help=command.help, description=command.help)
        if name == wanted:  # only the chosen subcommand's module is imported
            module = importlib.import_module(command.module)
            module.add_arguments(p)
            p.set_defaults(_run=module.run)
    return parser


def _complete(argv: list[str]) -> None:
    """Answer the shell's completion request (argcomplete's protocol: ``_ARGCOMPLETE`` set) and end the
    process; the parser has only the subcommand already typed in full."""
    import argcomplete

    words = argcomplete.split_line(os.environ.get("COMP_LINE", ""), int(os.environ.get("COMP_POINT", 0)))[3]
    argcomplete.autocomplete(_build(words[1:]))


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; ``argv`` None (the console script) means this is the process's entry: once
    the command has ended, late signals are ignored while the process exits."""
    from ..signals import EXIT_EARLY, Interrupted, exiting, running, startup

    entry = argv is None
    argv = sys.argv[1:] if argv is None else argv
    try:  # a signal may land as soon as the first handler is set, while startup() sets the others
        startup()  # SIGINT, SIGTERM, SIGHUP before a command takes over: a quiet end, exit 2
        if entry and "_ARGCOMPLETE" in os.environ:
            _complete(argv)
        args = _build(argv).parse_args(argv)
        running()
        return int(args._run(args) or 0)
    except Interrupted as exc:
        print(f"xac1: stopped by {exc.name}", file=sys.stderr)
        return EXIT_EARLY
    except KeyboardInterrupt:
        return 130
    finally:
        if entry:
            exiting()


if __name__ == "__main__":
    sys.exit(main())
