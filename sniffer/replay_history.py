"""A replay as a history record (``xac1_proto.history``, kind ``replay``): when, where, which device
and firmware, the verdict (SAME, DIFFERENT, THE DEVICE STOPPED ANSWERING) and exit status, and one
check a replayed line that did not get the captured answer back (its differences and the violation
codes the rulebook found in the new exchange). Its options and the recording itself are
``xac1_proto.history.command``'s, shared with ``xac1 fuzz``: recording never changes the exit status.
"""

from __future__ import annotations

import argparse
import datetime as _dt
from pathlib import Path
from typing import Any

VERDICTS = {0: "SAME", 1: "DIFFERENT", 3: "THE DEVICE STOPPED ANSWERING"}


def record_replay(args: argparse.Namespace, started: _dt.datetime, firmware: str | None, results: list[Any],
                  summary: dict[str, Any], status: int, signal: str | None, program: str) -> None:
    """Record the replay in the history store the options name (none with ``--no-history``)."""
    from xac1_proto.history.command import record_command_run
    from xac1_proto.history.model import CheckRecord, RunRecord, now

    def build(who: dict[str, Any]) -> RunRecord:
        checks = tuple(CheckRecord(name=f"line {r.line.i}", outcome="SKIPPED" if r.skipped else "DIFFERENT",
                                   rule=repr(r.line.raw.decode("latin-1")), codes=tuple(r.violations),
                                   message=r.skipped or "; ".join(r.comparison.differences))
                       for r in results if not r.same)
        return RunRecord(kind="replay", started=started, ended=now(),
                         verdict=VERDICTS.get(status, f"exit {status}"), exit_status=status,
                         verdict_line=", ".join(f"{k} {v}" for k, v in summary.items()
                                                if isinstance(v, int) and not isinstance(v, bool)),
                         port=args.port, firmware=firmware, interrupted=signal,
                         settings={"capture": " ".join(str(f) for f in args.files), "pace": args.pace,
                                   "motion": "allowed" if args.allow_motion else "not allowed",
                                   "safe range": args.safe_range or "-"},
                         files=(("report", str(Path(args.report).resolve())),) if args.report else (),
                         checks=checks, **who)

    record_command_run(args, program, build)
