"""``xac1 wireshark``: install the XA-C1 dissector, its Decode As entry and the extcap launcher into
Wireshark's personal folders (``install [--uninstall]``), or show those folders (``path``)."""

from __future__ import annotations

import argparse
import sys

HELP = "install the XA-C1 Wireshark dissector and extcap (install [--uninstall]), or show its folders (path)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    inst = sub.add_parser("install", help="copy the dissector, add the Decode As entry, put the extcap "
                                          "launcher")
    inst.add_argument("--uninstall", action="store_true", help="remove only what install put there")
    inst.add_argument("--profile", metavar="NAME",
                      help="the Wireshark profile to edit (default: the default one)")
    path = sub.add_parser("path", help="print the folders install uses")
    path.add_argument("--profile", metavar="NAME", help="the Wireshark profile (default: the default one)")


def run(args: argparse.Namespace) -> int:
    from sniffer.wireshark.install import InstallError, folders, install, uninstall
    from sniffer.wireshark.luagen import shipped_path

    where = folders(profile=args.profile)
    if args.action == "path":
        print(f"configuration:   {where.config}")
        print(f"profile:         {where.profile}")
        print(f"Decode As file:  {where.decode_as}")
        print(f"Lua plugins:     {where.lua_plugins}")
        print(f"extcap:          {where.extcap}")
        print(f"dissector:       {shipped_path()} (shipped; install copies it)")
        return 0
    try:
        done = uninstall(where) if args.uninstall else install(where)
    except InstallError as exc:
        print(f"xac1 wireshark: error: {exc}", file=sys.stderr)
        return 1
    for line in done:
        print(line)
    if not args.uninstall:
        print("open a recording: wireshark FILE.pcapng   (filter e.g. xac1.violation == \"alarm-ignored\")")
    return 0
