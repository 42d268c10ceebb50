"""``xac1 conformance``: run the installed conformance suite against a device (default: the simulator).

The suite is the ``conformance.checks`` package; this runs it with pytest in-process, isolated from
whatever pytest configuration the current directory has, with pytest's own terminal output off: the
operator reads the suite's words only (a live progress line, then the summary and the verdict, which is
always printed). Exit status (docs/conformance.md): 0 conforms, 1 a check failed, 2 bad options or
interrupted (Ctrl-C, SIGTERM, SIGHUP: the device is restored first), 3 the run could not go on, 4
incomplete (checks of stated rules not run; ``--allow-incomplete`` makes it 0).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import shlex
import sys
from pathlib import Path
from typing import Any

from .options import add_arguments

HELP = "run the conformance suite against a controller (default: the built-in simulator) and report"

INI = Path(__file__).resolve().parent / "conformance.ini"

__all__ = ["HELP", "add_arguments", "run"]


def _plugin_registered() -> bool:
    eps = importlib.metadata.entry_points(group="pytest11")
    return any(ep.value.split(":")[0] == "conformance.plugin" for ep in eps)


def pytest_args(args: argparse.Namespace) -> list[str]:
    """The pytest command line for these options."""
    checks = Path(__file__).resolve().parent / "checks"
    out = [str(checks), "-c", str(INI), "--rootdir", str(checks.parent), "-p", "no:cacheprovider",
           "-W", "ignore::pytest.PytestAssertRewriteWarning"]  # the CLI imported the package first
    if not _plugin_registered():
        out += ["-p", "conformance.plugin"]
    out += ["-v", "--tb=short"] if args.verbose else ["-p", "no:terminal", "--capture=sys"]
    for flag, value in (("--xac1-port", args.port), ("--xac1-safe-range", args.safe_range),
                        ("--xac1-report", args.report), ("--xac1-junit", args.junit),
                        ("--xac1-unit-id", args.unit_id), ("--xac1-operator", args.operator),
                        ("--xac1-station", args.station), ("--xac1-note", args.note),
                        ("--xac1-seed", args.seed), ("--xac1-examples", args.examples),
                        ("--xac1-timeout", args.timeout), ("--xac1-scratch-points", args.scratch_points),
                        ("--xac1-history", args.history), ("--xac1-history-fleet", args.history_fleet),
                        ("--xac1-readings", args.readings),
                        ("-k", args.select)):
        if value is not None:
            out += [flag, str(value)]
    if args.allow_motion:
        out.append("--xac1-allow-motion")
    if args.fresh:
        out.append("--xac1-fresh")
    if args.restore_mode0:
        out.append("--xac1-restore-mode0")
    if args.allow_incomplete:
        out.append("--xac1-allow-incomplete")
    if args.no_history:
        out.append("--xac1-no-history")
    command_line = shlex.join(["xac1", *sys.argv[1:]])
    return out + ["--xac1-cli", "--xac1-command-line", command_line]


def run(args: argparse.Namespace) -> int:
    from . import fleet

    if fleet.wanted(args):  # several devices: one child process each (conformance/fleet.py)
        return fleet.run(args)
    args.port = args.port[0] if args.port else None
    from .stopping import BEFORE_THE_RUN, Interrupted, StopPolicy

    policy = StopPolicy(what=BEFORE_THE_RUN).install()  # until the plugin takes over: a quiet end
    try:
        return _run(args, policy)
    except Interrupted as exc:
        print(f"xac1 conformance: INCOMPLETE: nothing was checked (the run was interrupted by {exc.name} "
              f"before it began; nothing was sent) (exit status 2)", flush=True)
        return 2
    finally:
        policy.uninstall()


def _run(args: argparse.Namespace, policy: Any) -> int:
    missing = [m for m in ("pytest", "hypothesis") if importlib.util.find_spec(m) is None]
    if missing:
        print(f"xac1 conformance: needs {' and '.join(missing)}: pip install 'xac1-proto[conformance]'",
              file=sys.stderr)
        return 2
    from xac1_proto.dut.settings import Settings, SettingsError

    try:
        settings = Settings.make(args.port, args.allow_motion, args.fresh, args.safe_range, args.seed,
                                 args.examples, args.timeout, args.scratch_points, args.restore_mode0,
                                 cli=True, readings=args.readings)
    except SettingsError as exc:
        print(f"xac1 conformance: {exc.in_cli_words()}", file=sys.stderr)
        return 2
    from .plugin import RUN_KEY, check_outputs

    problem = check_outputs(args.report, args.junit, settings.flag)
    if problem:
        print(f"xac1 conformance: {problem}; nothing was sent", file=sys.stderr)
        return 2
    print(f"xac1 conformance: testing {settings.port}", flush=True)
    import pytest

    class LastWord:
        """Keeps the run's verdict line and exit status (the plugin decides both)."""

        verdict: str | None = None
        status: int | None = None

        def pytest_unconfigure(self, config: pytest.Config) -> None:
            run = config.stash.get(RUN_KEY, None)
            if run is not None:
                self.verdict, self.status = run.verdict_line, run.exit_status

    last = LastWord()
    status = int(pytest.main(pytest_args(args), plugins=[last]))
    policy.ending("the run has ended; its verdict stands and follows")
    if last.status is not None:
        status = last.status
    if last.verdict:
        print(f"xac1 conformance: {last.verdict} (exit status {status})", flush=True)
    elif status == 2:
        by = f" by {policy.stopped_by}" if policy.stopped_by else ""
        print(f"xac1 conformance: INCOMPLETE: nothing was checked (the run was interrupted{by} before it "
              f"began) (exit status 2)", flush=True)
    return status
