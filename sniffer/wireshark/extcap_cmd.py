"""``xac1 extcap``: the Wireshark extcap entry point (run by the launcher ``xac1 wireshark install`` puts
in the extcap folder); the work is in ``sniffer.wireshark.extcap``."""

from __future__ import annotations

import argparse

HELP = "Wireshark extcap interface (XA-C1 tap, XA-C1 proxy); Wireshark runs it"


def add_arguments(p: argparse.ArgumentParser) -> None:
    from sniffer.wireshark.extcap import add_arguments as add

    add(p)


def run(args: argparse.Namespace) -> int:
    from sniffer.wireshark.extcap import run as extcap_run

    return extcap_run(args)
