"""``xac1 conformance``: run the installed conformance suite against a device (default: the simulator).

The suite is the ``conformance.checks`` package; this runs it with pytest in-process, isolated from
whatever pytest configuration the current directory has, and exits 0 only when every check of a stated
rule passed (skipped checks do not count against the device).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import sys
from pathlib import Path

HELP = "run the conformance suite against a controller (default: the built-in simulator) and report"

INI = Path(__file__).resolve().parent / "conformance.ini"


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
    p.add_argument("--junitxml", metavar="FILE", help="write JUnit XML results")
    p.add_argument("--seed", metavar="N", type=int, help="seed of the random command sequences (default 0)")
    p.add_argument("--examples", metavar="N", type=int, help="random command sequences to try")
    p.add_argument("--timeout", metavar="S", type=float, help="seconds to wait for an answer")
    p.add_argument("-k", metavar="EXPR", dest="select", help="run only the checks matching EXPR (pytest -k)")
    p.add_argument("-v", "--verbose", action="store_true", help="show pytest's own output and tracebacks")
    from .fleet import add_arguments as fleet_arguments

    fleet_arguments(p)


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
    out += ["-v", "--tb=short"] if args.verbose else ["-q", "--no-header", "--tb=no", "-rN"]
    for flag, value in (("--xac1-port", args.port), ("--xac1-safe-range", args.safe_range),
                        ("--xac1-report", args.report), ("--junitxml", args.junitxml),
                        ("--xac1-seed", args.seed), ("--xac1-examples", args.examples),
                        ("--xac1-timeout", args.timeout), ("--xac1-scratch-points", args.scratch_points),
                        ("-k", args.select)):
        if value is not None:
            out += [flag, str(value)]
    if args.allow_motion:
        out.append("--xac1-allow-motion")
    if args.fresh:
        out.append("--xac1-fresh")
    if args.restore_mode0:
        out.append("--xac1-restore-mode0")
    return out + ["--xac1-cli"]


def run(args: argparse.Namespace) -> int:
    from . import fleet

    if fleet.wanted(args):  # several devices: one child process each (conformance/fleet.py)
        return fleet.run(args)
    args.port = args.port[0] if args.port else None
    missing = [m for m in ("pytest", "hypothesis") if importlib.util.find_spec(m) is None]
    if missing:
        print(f"xac1 conformance: needs {' and '.join(missing)}: pip install 'xac1-proto[conformance]'",
              file=sys.stderr)
        return 2
    from .settings import Settings, SettingsError

    try:
        Settings.make(args.port, args.allow_motion, args.fresh, args.safe_range, args.seed, args.examples,
                      args.timeout, args.scratch_points, args.restore_mode0, cli=True)
    except SettingsError as exc:
        print(f"xac1 conformance: {str(exc).replace('--xac1-', '--')}", file=sys.stderr)
        return 2
    if args.report and Path(args.report).suffix.lower() not in (".md", ".markdown", ".html", ".htm"):
        print(f"xac1 conformance: --report {args.report}: the name must end in .md or .html", file=sys.stderr)
        return 2
    import pytest

    from .plugin import RUN_KEY

    class LastWord:
        """Keeps the run's verdict line, printed after pytest's own counts (which include information
        records and so differ from the suite's)."""

        verdict: str | None = None

        def pytest_unconfigure(self, config: pytest.Config) -> None:
            run = config.stash.get(RUN_KEY, None)
            self.verdict = run.verdict_line if run is not None else None

    last = LastWord()
    status = int(pytest.main(pytest_args(args), plugins=[last]))
    if last.verdict:
        print(f"xac1 conformance: {last.verdict} (exit status {status})", flush=True)
    return status
