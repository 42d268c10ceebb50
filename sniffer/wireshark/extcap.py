"""``xac1 extcap``: Wireshark's extcap interface, so "XA-C1 tap" and "XA-C1 proxy" show in its
interface list and capture live, decoded, verdicts included.

How this works. Wireshark runs every program in its extcap folder (``xac1 wireshark install`` puts a
launcher there) with ``--extcap-interfaces`` (which interfaces), then for the one picked
``--extcap-dlts`` (its link type: RTAC serial, 250) and ``--extcap-config`` (the options to ask for:
the tap ports, or the device port and the host side's TCP port or pty link), and finally ``--capture
--fifo PATH`` with those options. The capture is ``xac1 sniff`` or ``xac1 proxy`` itself, with its
recording forced to pcapng and written into the FIFO (``sniffer.io.pcapng_writer``: one packet per
chunk, verdicts as packet comments that the dissector shows as expert info). Wireshark stops it with
SIGTERM; the recording is closed then. The text view goes nowhere (Wireshark does not read it), and
the shell's messages reach stderr only when the capture fails (Wireshark shows stderr as an error).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
from typing import IO, Final

from xac1_proto import __version__, spec

from ..io.pcapng_writer import LINKTYPE_RTAC_SERIAL

TAP: Final = "xac1tap"
PROXY: Final = "xac1proxy"
INTERFACES: Final = {TAP: "XA-C1 tap (two receive-only taps, a Y-cable)",
                     PROXY: "XA-C1 proxy (between host software and the controller)"}

# number, option, display, type, extra: one row an extcap config argument, per interface.
_TIMEOUT = ("--timeout", "No-answer timeout (s)", "double",
            f"{{default={spec.NO_ANSWER_TIMEOUT_S}}}{{range=0.01,600}}")
CONFIG: Final[dict[str, tuple[tuple[str, str, str, str], ...]]] = {
    TAP: (("--host-tap", "Host tap port", "string",
           "{required=true}{tooltip=serial port wired to the host's TX}"),
          ("--device-tap", "Device tap port", "string",
           "{required=true}{tooltip=serial port wired to the controller's TX}"),
          ("--baud", "Baud", "integer", f"{{default={spec.BAUD}}}"),
          _TIMEOUT),
    PROXY: (("--device", "Controller port", "string",
             "{required=true}{tooltip=a path or a pyserial URL such as socket://127.0.0.1:5020}"),
            ("--tcp", "Host side TCP port (127.0.0.1)", "string",
             "{tooltip=host software connects here; leave empty to offer a pty}"),
            ("--link", "Host side pty link", "string", "{tooltip=with no TCP port: a symlink to the pty}"),
            ("--baud", "Baud", "integer", f"{{default={spec.BAUD}}}"),
            _TIMEOUT),
}


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="xac1 extcap", description=HELP)
    add_arguments(p)
    return p


HELP: Final = "Wireshark extcap interface: XA-C1 tap and proxy as live capture interfaces"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--extcap-interfaces", action="store_true", help="list the interfaces")
    p.add_argument("--extcap-interface", choices=tuple(INTERFACES), help="the interface asked about")
    p.add_argument("--extcap-dlts", action="store_true", help="the interface's link types")
    p.add_argument("--extcap-config", action="store_true", help="the interface's options")
    p.add_argument("--extcap-version", default=None, help="Wireshark's version (ignored)")
    p.add_argument("--extcap-capture-filter", default=None, help="(not supported: ignored)")
    p.add_argument("--debug", action="store_true", help="(ignored)")
    p.add_argument("--debug-file", default=None, help="(ignored)")
    p.add_argument("--capture", action="store_true", help="capture into --fifo")
    p.add_argument("--fifo", help="where to write the pcapng stream")
    p.add_argument("--host-tap")
    p.add_argument("--device-tap")
    p.add_argument("--device")
    p.add_argument("--tcp", default="")
    p.add_argument("--link", default="")
    p.add_argument("--baud", type=int, default=spec.BAUD)
    p.add_argument("--timeout", type=float, default=spec.NO_ANSWER_TIMEOUT_S)


def interfaces(out: IO[str]) -> None:
    out.write(f"extcap {{version={__version__}}}\n")
    for value, display in INTERFACES.items():
        out.write(f"interface {{value={value}}}{{display={display}}}\n")


def dlts(out: IO[str]) -> None:
    out.write(f"dlt {{number={LINKTYPE_RTAC_SERIAL}}}{{name=RTAC_SERIAL}}"
              f"{{display=RTAC serial (XA-C1: TX host, RX controller)}}\n")


def config(interface: str, out: IO[str]) -> None:
    for number, (call, display, kind, extra) in enumerate(CONFIG[interface]):
        out.write(f"arg {{number={number}}}{{call={call}}}{{display={display}}}{{type={kind}}}{extra}\n")


def _shell_args(args: argparse.Namespace) -> tuple[str, list[str]]:
    """The ``xac1 sniff`` / ``xac1 proxy`` command line this capture runs."""
    common = ["--baud", str(args.baud), "--timeout", str(args.timeout), "--record", args.fifo]
    if args.extcap_interface == TAP:
        if not args.host_tap or not args.device_tap:
            raise ValueError("XA-C1 tap needs both --host-tap and --device-tap")
        return "sniffer.sniff_cli", ["--host-tap", args.host_tap, "--device-tap", args.device_tap, *common]
    if not args.device:
        raise ValueError("XA-C1 proxy needs --device (the controller's port)")
    side = ["--tcp", args.tcp] if args.tcp else ["--pty", *(["--link", args.link] if args.link else [])]
    return "sniffer.proxy_cli", ["--device", args.device, *side, *common]


def capture(args: argparse.Namespace) -> int:
    import importlib

    if not args.fifo:
        print("xac1 extcap: --capture needs --fifo PATH", file=sys.stderr)
        return 2
    try:
        module_name, argv = _shell_args(args)
    except ValueError as exc:
        print(f"xac1 extcap: {exc}", file=sys.stderr)
        return 2
    module = importlib.import_module(module_name)
    p = argparse.ArgumentParser(prog=f"xac1 extcap ({args.extcap_interface})")
    module.add_arguments(p)
    shell_args = p.parse_args(argv)
    shell_args.record_format = "pcapng"  # the FIFO's name says nothing of the format
    said = io.StringIO()  # Wireshark shows an extcap's stderr as an error: only say it on failure
    with open(os.devnull, "w") as null, contextlib.redirect_stdout(null), contextlib.redirect_stderr(said):
        try:
            code = int(module.run(shell_args) or 0)
        except BrokenPipeError:  # Wireshark stopped reading the FIFO: the capture is over
            code = 0
    if code != 0:
        sys.stderr.write(said.getvalue())
    return code


def run(args: argparse.Namespace) -> int:
    if args.extcap_interfaces:
        interfaces(sys.stdout)
        return 0
    if args.extcap_interface is None:
        print("xac1 extcap: give --extcap-interfaces, or --extcap-interface with --extcap-dlts, "
              "--extcap-config or --capture", file=sys.stderr)
        return 2
    if args.extcap_dlts:
        dlts(sys.stdout)
        return 0
    if args.extcap_config:
        config(args.extcap_interface, sys.stdout)
        return 0
    if args.capture:
        return capture(args)
    print("xac1 extcap: nothing to do (--extcap-dlts, --extcap-config or --capture)", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    return run(_parser().parse_args(argv))
