"""The ``xac1`` console script: one subcommand a module, imported only when it runs.

Each subcommand module has ``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from typing import Final

from .. import __version__

# name -> module implementing it
COMMANDS: Final[dict[str, str]] = {
    "parse": "xac1_proto.cli.parse_cmd",
    "sim": "xac1_proto.sim.cli",
    "send": "xac1_proto.cli.send_cmd",
    "console": "xac1_proto.cli.console_cmd",
    "conformance": "conformance.cli",
    "sniff": "sniffer.sniff_cli",
    "proxy": "sniffer.proxy_cli",
    "decode": "sniffer.decode_cli",
    "wireshark": "xac1_proto.cli.wireshark_cmd",
    "extcap": "xac1_proto.cli.extcap_cmd",
}


def _exists(module_name: str) -> bool:
    try:
        return importlib.util.find_spec(module_name) is not None
    except ModuleNotFoundError:
        return False


def _build(argv: list[str]) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="xac1",
        description="Protocol analyzer and conformance kit for the SUS XA-C1 actuator controller.",
    )
    parser.add_argument("--version", action="version", version=f"xac1 {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    wanted = next((a for a in argv if not a.startswith("-")), None)
    for name, module_name in COMMANDS.items():
        if not _exists(module_name):  # a subcommand still being built
            continue
        module = importlib.import_module(module_name)
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        if name == wanted:
            module.add_arguments(p)
            p.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = _build(argv).parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
