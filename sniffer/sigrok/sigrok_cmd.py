"""``xac1 sigrok``: install the XA-C1 protocol decoder into the user's sigrok decoder folder
(``install [--uninstall]``) for PulseView and sigrok-cli, or show that folder (``path``)."""

from __future__ import annotations

import argparse
import sys

HELP = "install the XA-C1 sigrok decoder for PulseView and sigrok-cli (install [--uninstall]), or show " \
       "its folder (path)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    inst = sub.add_parser("install", help="copy the decoder into $XDG_DATA_HOME/libsigrokdecode/decoders/"
                                          "xac1 (~/.local/share/... without XDG_DATA_HOME)")
    inst.add_argument("--uninstall", action="store_true", help="remove only what install put there")
    sub.add_parser("path", help="print the folder install uses")


def run(args: argparse.Namespace) -> int:
    from sniffer.sigrok.install import CLI_HINT, PULSEVIEW_HINT, InstallError, decoder_dir, install, uninstall
    from sniffer.sigrok.pdgen import shipped_dir

    folder = decoder_dir()
    if args.action == "path":
        print(f"decoders: {folder.parent}")
        print(f"xac1:     {folder}")
        print(f"shipped:  {shipped_dir()} (install copies it)")
        return 0
    try:
        done = uninstall(folder) if args.uninstall else install(folder)
    except InstallError as exc:
        print(f"xac1 sigrok: error: {exc}", file=sys.stderr)
        return 1
    for line in done:
        print(line)
    if not args.uninstall:
        print(PULSEVIEW_HINT)
        print(CLI_HINT)
    return 0
