"""The options of ``xac1 conformance`` (one device, or a fleet): one argparse definition that the
command line and the pytest plugin's fleet hand-over share, so neither imports the other."""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", metavar="URL", action="append",
                   help="device under test: a pyserial URL (socket://HOST:PORT, rfc2217://..., hwgrep://...) "
                        "or a device path; default: the built-in simulator. Repeat it to test several "
                        "devices at once (see --ports)")
    p.add_argument("--allow-motion", action="store_true",
                   help="allow moving the actuator (implied for the simulator); needs --safe-range")
    p.add_argument("--safe-range", metavar="LO:HI",
                   help="positions the actuator may be moved to, decimal or 0x-hex, e.g. 0:0x1000")
    p.add_argument("--fresh", action="store_true",
                   help="the device was just powered on and never homed: run the power-on checks first")
    p.add_argument("--scratch-points", metavar="LIST",
                   help="points the suite may overwrite even if never written before, e.g. 1,2,F (default on "
                        "a real device: only points that hold data, which it writes back at the end)")
    p.add_argument("--restore-mode0", action="store_true",
                   help="send 0CM0 last: the controller ends in mode 0 (external start inputs enabled again)")
    p.add_argument("--report", metavar="FILE", help="write an acceptance report (.md or .html)")
    p.add_argument("--junit", "--junitxml", metavar="FILE", dest="junit",
                   help="write JUnit XML: checks of stated rules as tests, information as properties")
    p.add_argument("--unit-id", metavar="TEXT", help="the unit's serial number or asset tag (in the report)")
    p.add_argument("--operator", metavar="NAME", help="who ran the acceptance (in the report)")
    p.add_argument("--station", metavar="TEXT", help="the test station or rack position (in the report)")
    p.add_argument("--note", metavar="TEXT", help="a note for the report")
    p.add_argument("--allow-incomplete", action="store_true",
                   help="exit 0 when nothing failed although checks were not run (the verdict still says "
                        "INCOMPLETE): for a deliberately partial run")
    p.add_argument("--seed", metavar="N", type=int, help="seed of the random command sequences (default 0)")
    p.add_argument("--examples", metavar="N", type=int, help="random command sequences to try")
    p.add_argument("--timeout", metavar="S", type=float, help="seconds to wait for an answer")
    p.add_argument("--readings", choices=("notice", "error"), default=None,
                   help="our readings of the silent vendor text as notices (default) or as errors: only "
                        "errors fail a device")
    p.add_argument("-k", metavar="EXPR", dest="select", help="run only the checks matching EXPR (pytest -k)")
    p.add_argument("-v", "--verbose", action="store_true", help="show pytest's own output and tracebacks")
    from xac1_proto.history.where import add_arguments as history_arguments

    history_arguments(p)
    p.add_argument("--history-fleet", metavar="ID", help=argparse.SUPPRESS)  # a fleet's child: its fleet
    from .fleet import add_arguments as fleet_arguments

    fleet_arguments(p)
