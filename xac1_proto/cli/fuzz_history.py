"""A fuzz run as a history record (``xac1_proto.history``, kind ``fuzz``), built from its ``RunSummary``.

How this works: the verdict is ``FINDINGS`` when the run found anything (whatever ended it),
``INTERRUPTED`` when a signal ended it before a finding, ``INCOMPLETE`` when it ended early otherwise
(a failure of the run itself), else ``NO FINDING``; the exit status is the command's. Each finding is one
failed check named after its kind (``silence``, ``answer``, ``state``; a second of a kind ``state 2``...,
so ``xac1 history list --rule silence`` finds every run with a silence), with the engine's violation
codes and the lines that produce it. The settings are the seed, the cases asked for, motion and the safe
range, the answer window; the files are the report, JUnit and each finding's capture. The options and
the recording (spooled when the store cannot be reached, never changing the exit status) are
``xac1_proto.history.command``'s, shared with ``xac1 replay``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from xac1_proto.dut.settings import Settings
    from xac1_proto.fuzz.results import Reported, RunSummary
    from xac1_proto.history.model import CheckRecord, RunRecord

    from .fuzz_run import Limits

NO_FINDING: Final = "NO FINDING"
FINDINGS: Final = "FINDINGS"
INTERRUPTED: Final = "INTERRUPTED"
INCOMPLETE: Final = "INCOMPLETE"


def verdict(summary: RunSummary) -> str:
    if summary.findings:
        return FINDINGS
    if summary.interrupted:
        return INTERRUPTED
    return INCOMPLETE if summary.stopped else NO_FINDING


def finding_checks(findings: tuple[Reported, ...]) -> tuple[CheckRecord, ...]:
    """One failed check a finding, named after its kind (numbered from the second of a kind on)."""
    from xac1_proto.fuzz.results import wire
    from xac1_proto.history.model import CheckRecord

    from .fuzz_files import KIND_MEANING

    seen: Counter[str] = Counter()
    checks = []
    for r in findings:
        f = r.finding
        seen[f.kind] += 1
        how = "" if r.shrunk else f" (not shrunk: {r.why})"
        checks.append(CheckRecord(
            name=f.kind if seen[f.kind] == 1 else f"{f.kind} {seen[f.kind]}", outcome="FAIL",
            rule=KIND_MEANING[f.kind], topic=f.kind, codes=f.codes,
            message=f"case {r.case}: sent {' '.join(wire(x) for x in f.lines)}{how}; seen: {f.detail}"))
    return tuple(checks)


def run_record(summary: RunSummary, args: argparse.Namespace, settings: Settings, limits: Limits,
               started: _dt.datetime, ended: _dt.datetime, who: dict[str, Any]) -> RunRecord:
    """The history record of a finished (or interrupted) fuzz run; ``who`` as ``history.command``'s
    ``identity`` gives it."""
    from xac1_proto.fuzz.results import outcome
    from xac1_proto.history.model import RunRecord

    asked = str(limits.cases) if limits.cases is not None else f"for {limits.seconds:g} s"
    files = [(what, str(Path(path).resolve())) for what, path in (("report", args.report),
                                                                   ("junit", args.junit)) if path]
    files += [("capture", str(Path(r.capture).resolve())) for r in summary.findings if r.capture]
    return RunRecord(kind="fuzz", started=started, ended=ended, verdict=verdict(summary),
                     exit_status=summary.exit,
                     verdict_line=f"{summary.cases} cases (seed {summary.seed}): {outcome(summary)}",
                     port=summary.port, firmware=summary.version, interrupted=summary.interrupted,
                     settings={"seed": str(summary.seed), "cases": asked,
                               "motion": "allowed" if summary.motion else "not allowed",
                               "safe range": args.safe_range or "-",
                               "answer window": f"{settings.timeout:g} s"},
                     files=tuple(files), checks=finding_checks(summary.findings), **who)


def record_fuzz(summary: RunSummary, args: argparse.Namespace, settings: Settings, limits: Limits,
                started: _dt.datetime, program: str) -> None:
    """Record the run in the history store the options name (none with ``--no-history``)."""
    from xac1_proto.history.command import record_command_run
    from xac1_proto.history.model import now

    record_command_run(args, program,
                       lambda who: run_record(summary, args, settings, limits, started, now(), who))
