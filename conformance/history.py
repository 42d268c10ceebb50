"""A conformance run as a history record (``xac1_proto.history``): built from the plugin's run and its
``Report`` when the session ends, then recorded (or spooled, when the store cannot be reached).

How this works: every check the run collected becomes a ``CheckRecord``: those it judged with their
outcome, rule and the violation codes of their exchanges; those it never reached as NOT RUN, or
INTERRUPTED for the one a signal or a failing device cut short. The settings are the report's (motion,
safe range, random sequences, timeout, points the suite may write...), with the rulebook's readings
setting where the kit has one. Recording never changes the verdict or the exit status: a failure to
record is one line on stderr.
"""

from __future__ import annotations

import shlex
import socket
import sys
from pathlib import Path
from typing import Any

from xac1_proto.history.model import CheckRecord, RunRecord, now

PROGRAM = "xac1 conformance"


def _codes(result: Any) -> tuple[str, ...]:
    return tuple(dict.fromkeys(v.code for p in result.probes for v in p.violations))


def checks(run: Any, rep: Any) -> tuple[CheckRecord, ...]:
    """Every collected check: judged ones with their outcome, the others NOT RUN or INTERRUPTED."""
    judged = {r.nodeid: r for r in rep.junit}
    out = []
    for nodeid, name, info in run.collected:
        r = judged.get(nodeid)
        if r is not None:
            out.append(CheckRecord(name=r.check, outcome=r.verdict, rule=r.rule, topic=r.topic,
                                   codes=_codes(r), message=r.message, info=r.info))
        else:
            cut = nodeid in run.interrupted
            out.append(CheckRecord(name=name, outcome="INTERRUPTED" if cut else "NOT RUN",
                                   topic=Path(nodeid.split("::")[0]).stem.removeprefix("test_"), info=info))
    return tuple(out)


def run_record(run: Any, rep: Any, config: Any) -> RunRecord:
    """The history record of a finished (or interrupted) run."""
    c, s, who = config, run.settings, run.identity
    files = tuple((what, str(Path(path).resolve())) for what, path in (("report", c.getoption("xac1_report")),
                                                                      ("junit", c.getoption("xac1_junit")))
                  if path and not any(path in p for p in run.write_problems))
    readings = getattr(s, "readings", None)
    return RunRecord(
        kind="conformance", started=run.started, ended=now(),
        verdict=rep.head if run.total else "NOT TESTED", verdict_line=run.verdict_line or "",
        exit_status=int(run.exit_status if run.exit_status is not None else 2),
        station=who.get("station") or socket.gethostname(), operator=who.get("operator"), port=s.port,
        unit=who.get("unit_id"), firmware=rep.version if rep.version != "unknown" else None,
        interrupted=run.interrupted_by, kit_version=rep.kit_version,
        fleet=c.getoption("xac1_history_fleet"),
        command_line=run.command_line or shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        readings=str(readings) if readings is not None else None,
        settings={label: str(value) for label, value in rep.options}, files=files, checks=checks(run, rep))


def record_run(run: Any, rep: Any, config: Any, url: str) -> None:
    """Record the run in the store at ``url`` (spooled when unreachable); never raises."""
    try:
        from xac1_proto.history.recorder import record

        record(run_record(run, rep, config), url, PROGRAM)
    except Exception as exc:  # noqa: BLE001 - the verdict and exit status stand whatever recording does
        print(f"{PROGRAM}: history: the run could not be recorded: {type(exc).__name__}: {exc}",
              file=sys.stderr, flush=True)
