"""A replay as a history record (``xac1_proto.history``, kind ``replay``): when, where, which device
and firmware, the verdict (SAME, DIFFERENT, THE DEVICE STOPPED ANSWERING) and exit status, and one
check a replayed line that did not get the captured answer back (its differences and the violation
codes the rulebook found in the new exchange). Recording never changes the exit status.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import shlex
import socket
import sys
from pathlib import Path
from typing import Any

VERDICTS = {0: "SAME", 1: "DIFFERENT", 3: "THE DEVICE STOPPED ANSWERING"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    from xac1_proto.history.where import add_arguments as history_arguments

    history_arguments(p)
    p.add_argument("--unit-id", metavar="TEXT", help="the unit's serial number or asset tag (in the history)")
    p.add_argument("--operator", metavar="NAME", help="who ran the replay (in the history)")
    p.add_argument("--station", metavar="TEXT",
                   help="the test station (in the history; default: the host name)")


def record_replay(args: argparse.Namespace, started: _dt.datetime, firmware: str | None, results: list[Any],
                  summary: dict[str, Any], status: int, signal: str | None, program: str) -> None:
    """Record the replay in the history store the options name (none with ``--no-history``)."""
    from xac1_proto.history.where import target

    url = target(args.history, args.no_history)
    if url is None:
        return
    try:
        from xac1_proto import __version__
        from xac1_proto.history.model import CheckRecord, RunRecord, now
        from xac1_proto.history.recorder import record

        checks = tuple(CheckRecord(name=f"line {r.line.i}", outcome="SKIPPED" if r.skipped else "DIFFERENT",
                                   rule=repr(r.line.raw.decode("latin-1")), codes=tuple(r.violations),
                                   message=r.skipped or "; ".join(r.comparison.differences))
                       for r in results if not r.same)
        run = RunRecord(kind="replay", started=started, ended=now(),
                        verdict=VERDICTS.get(status, f"exit {status}"), exit_status=status,
                        verdict_line=", ".join(f"{k} {v}" for k, v in summary.items()
                                               if isinstance(v, int) and not isinstance(v, bool)),
                        station=args.station or socket.gethostname(), operator=args.operator, port=args.port,
                        unit=args.unit_id, firmware=firmware, interrupted=signal, kit_version=__version__,
                        command_line=shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
                        settings={"capture": " ".join(str(f) for f in args.files), "pace": args.pace,
                                  "motion": "allowed" if args.allow_motion else "not allowed",
                                  "safe range": args.safe_range or "-"},
                        files=(("report", str(Path(args.report).resolve())),) if args.report else (),
                        checks=checks)
        record(run, url, program)
    except Exception as exc:  # noqa: BLE001 - the exit status stands whatever recording does
        print(f"{program}: history: the run could not be recorded: {type(exc).__name__}: {exc}",
              file=sys.stderr, flush=True)
