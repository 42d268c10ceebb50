"""The pytest plugin (entry point ``pytest11``): options, the device fixtures, ordering, verdicts, report.

How it works: importing this module costs nothing beyond pytest itself; every hook returns at once
unless the run uses an ``--xac1-*`` option or collects the checks of ``conformance.checks``. Then the
options become a ``Settings`` (bad values stop the run with a usage error), the checks are ordered
(power-on checks first, the random-sequence check last) and those the settings forbid are skipped with
the reason. The device is opened before the first check (a port that does not open: no check starts);
the first that needs it snapshots the points and OUT ports; every check starts with any latched alarm
reset. Each check's outcome becomes a ``Result`` with the rule from
its docstring and the probes as evidence. A ``DeviceAbort`` (no port, no answer, emergency stop) is no
verdict on the check that met it: the run stops, the rest count as not run, exit status 3. A check whose
last probe got no byte back is followed at once by the liveness check, so a device that stopped
answering (``StoppedAnswering``) takes back the verdict of the check it stopped in (listed as
interrupted) instead of failing it. When the session ends, even after Ctrl-C, the device is restored
and verified (Ctrl-C is ignored meanwhile), then the summary table and the report file are written,
whatever stopped the run; a restore the device did not answer is reported as not verified (exit 3).
SIGTERM and SIGHUP end the run as Ctrl-C does (``stopping.StopPolicy``); a second signal is ignored and
said so. The verdict and exit status come from ``report.Report``: 0 conforms, 1 a check failed, 2
interrupted, 3 could not go on, 4 incomplete (checks of stated rules not run; 0 with
``--xac1-allow-incomplete``). Several devices (``--xac1-port`` repeated, ``--xac1-ports FILE`` or
``--xac1-report-dir``): ``pytest_cmdline_main`` hands the run over to ``conformance.fleet`` before
pytest configures or collects anything, one ``xac1 conformance --port X`` process per device.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import functools
import os
import sys
from pathlib import Path
from typing import Any

import pytest

CHECKS_DIR = Path(__file__).resolve().parent / "checks"
MARKERS = {
    "xac1_motion": "the check moves the actuator (needs --xac1-allow-motion and a safe range)",
    "xac1_fresh": "the check needs a freshly powered-on, never-homed device (--xac1-fresh); runs first",
    "xac1_info": "records what the device does where docs/protocol.md is silent; never a failed verdict",
    "xac1_last": "runs after every other check",
}


class Xac1Run:
    """Everything one session knows: settings, the device, its snapshot, results, restore outcome."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.settings: Any = None
        self.dut: Any = None
        self.opened: Any = None  # the device opened before the first check, until the fixture takes it
        self.snapshot: Any = None
        self.restore_report: Any = None
        self.restored = False
        self.results: list[Any] = []
        self.abort: str | None = None
        self.no_answer = False  # the abort: the device never answered at all
        self.stopped = False  # the abort: the device answered, then stopped answering
        self.interrupted: list[str] = []  # nodeids of checks the abort cut short (no verdict)
        self.collected: list[tuple[str, str, bool]] = []  # (nodeid, check name, information record)
        self.total = 0  # checks collected (those never run are counted in the report)
        self.total_info = 0  # of which information records
        self.verdict_line: str | None = None  # as printed in the summary (``xac1 conformance`` repeats it)
        self.started = _dt.datetime.now().astimezone()
        self.active = False
        self.identity: dict[str, str | None] = {}  # unit_id, operator, station, note
        self.command_line = ""
        self.deselected = 0  # checks of stated rules left out with -k
        self.interrupted_by: str | None = None  # SIGINT, SIGTERM, SIGHUP
        self.policy: Any = None  # stopping.StopPolicy
        self.progress: Any = None  # progress.Progress (xac1 conformance without pytest's terminal)
        self.exit_status: int | None = None
        self.write_problems: list[str] = []  # output files that could not be written

    def cannot_go_on(self, item: pytest.Item, report: pytest.TestReport,
                     excinfo: pytest.ExceptionInfo[BaseException]) -> None:
        """A check met a device abort (no answer, an emergency stop, a lost port): note why, stop the
        session, and give a check cut short no verdict, nor any record it made."""
        from xac1_proto.dut.device import NoAnswer, PortLost, StoppedAnswering

        self.abort = self.abort or str(excinfo.value)
        self.no_answer = self.no_answer or excinfo.errisinstance(NoAnswer)
        self.stopped = self.stopped or excinfo.errisinstance((StoppedAnswering, PortLost))
        item.session.shouldstop = "xac1: the run cannot go on (the XA-C1 conformance summary above says why)"
        if report.when != "setup" and item.nodeid not in self.interrupted:
            # Cut short (or its last exchange met the silence).
            self.interrupted.append(item.nodeid)
            self.results = [r for r in self.results if r.nodeid != item.nodeid]
            if self.dut is not None:
                self.dut.infos = [i for i in self.dut.infos if all(p.test != item.nodeid for p in i.probes)]

    def record(self, item: pytest.Item, report: pytest.TestReport, call: pytest.CallInfo[None]) -> None:
        """A check's verdict from one of its phases (a failed teardown replaces its call's verdict),
        kept and shown in the JUnit file as its rule, verdict and first probes."""
        from .results import result_from

        self.results = [r for r in self.results if r.nodeid != item.nodeid or report.when != "teardown"]
        result = result_from(item, report, call, self.dut)
        self.results.append(result)
        report.user_properties += [("rule", result.rule), ("verdict", result.verdict)]
        report.user_properties += [("evidence", p.show()) for p in result.probes[:4]]


RUN_KEY = pytest.StashKey[Xac1Run]()
EXIT_INCOMPLETE = 3  # the run could not go on: no port, no answer, emergency stop...


def pytest_addoption(parser: pytest.Parser) -> None:
    g = parser.getgroup("xac1", "XA-C1 conformance suite")
    g.addoption("--xac1-port", metavar="URL", action="append", default=None,
                help="device under test: a pyserial URL or device path (default: the built-in simulator). "
                     "Repeat it to test several devices at once, one process each, as `xac1 conformance "
                     "--port A --port B` does (see --xac1-report-dir)")
    g.addoption("--xac1-ports", metavar="FILE", default=None,
                help="test every port listed in FILE at once (one URL a line, optionally followed by the "
                     "unit's id; # comments), each in its own process")
    g.addoption("--xac1-report-dir", metavar="DIR", default=None,
                help="with several ports: write DIR/<port>.html, DIR/<port>.xml (JUnit), DIR/<port>.log and "
                     "DIR/fleet.html, DIR/fleet.md")
    g.addoption("--xac1-allow-motion", action="store_true", default=False,
                help="allow moving the actuator (implied for the simulator); needs --xac1-safe-range")
    g.addoption("--xac1-fresh", action="store_true", default=False,
                help="the device was just powered on and never homed: run the power-on checks first")
    g.addoption("--xac1-safe-range", metavar="LO:HI", default=None,
                help="positions the actuator may be moved to, decimal or 0x-hex (e.g. 0:0x1000)")
    g.addoption("--xac1-seed", metavar="N", type=int, default=None,
                help="seed of the random command sequences (default 0: the same sequences every run)")
    g.addoption("--xac1-examples", metavar="N", type=int, default=None,
                help="random command sequences to try (default 30 on the simulator, 10 on a device)")
    g.addoption("--xac1-readings", choices=("notice", "error"), default=None,
                help="our readings of the silent vendor text as notices (default) or as errors: only "
                     "errors fail a device")
    g.addoption("--xac1-timeout", metavar="S", type=float, default=None,
                help="seconds to wait for an answer (default 0.5; 0.2 on the built-in simulator)")
    g.addoption("--xac1-report", metavar="FILE", default=None,
                help="write the acceptance report to FILE (.md for Markdown, .html for HTML)")
    g.addoption("--xac1-scratch-points", metavar="LIST", default=None,
                help="points the suite may overwrite even if never written before (e.g. 1,2,F); used "
                     "first, restored at the end when they held data. Default on a real device: only "
                     "points that held data (they can be written back)")
    g.addoption("--xac1-restore-mode0", action="store_true", default=False,
                help="send 0CM0 last, so the controller ends in mode 0 (external start inputs enabled)")
    g.addoption("--xac1-allow-incomplete", action="store_true", default=False,
                help="exit 0 for a run with no failure even when checks of stated rules were not run "
                     "(a deliberately partial run; the verdict still says INCOMPLETE)")
    g.addoption("--xac1-unit-id", metavar="TEXT", default=None, help="the unit's serial number or asset tag")
    g.addoption("--xac1-operator", metavar="NAME", default=None, help="who ran the acceptance")
    g.addoption("--xac1-station", metavar="TEXT", default=None, help="the test station or rack position")
    g.addoption("--xac1-note", metavar="TEXT", default=None, help="a note for the report")
    g.addoption("--xac1-junit", metavar="FILE", default=None,
                help="write JUnit XML: checks of stated rules as tests, information as properties")
    g.addoption("--xac1-history", metavar="URL", default=None,
                help="record the run in this history store: a SQLite file or sqlite:///FILE, or "
                     "postgresql://USER@HOST/DB (default: $XAC1_HISTORY, else "
                     "$XDG_DATA_HOME/xac1/history.sqlite)")
    g.addoption("--xac1-no-history", action="store_true", default=False,
                help="record nothing in the history store")
    g.addoption("--xac1-history-fleet", default=None, help=argparse.SUPPRESS)  # the fleet run's id
    g.addoption("--xac1-cli", action="store_true", default=False, help=argparse.SUPPRESS)
    g.addoption("--xac1-command-line", default="", help=argparse.SUPPRESS)


def _options_used(config: pytest.Config) -> bool:
    names = tuple(CLI_OPTION)  # any xac1 option the operator gives activates the plugin
    return any(config.getoption(n) not in (None, False) for n in names)


def _single_port(config: pytest.Config) -> str | None:
    ports = config.getoption("xac1_port") or []
    return ports[0] if ports else None


# Plugin option (dest) -> the ``xac1 conformance`` option it is, for the fleet hand-over.
CLI_OPTION: dict[str, str] = {
    "xac1_port": "--port", "xac1_ports": "--ports", "xac1_report_dir": "--report-dir",
    "xac1_allow_motion": "--allow-motion", "xac1_fresh": "--fresh", "xac1_safe_range": "--safe-range",
    "xac1_seed": "--seed", "xac1_examples": "--examples", "xac1_timeout": "--timeout",
    "xac1_report": "--report", "xac1_scratch_points": "--scratch-points",
    "xac1_restore_mode0": "--restore-mode0", "xac1_allow_incomplete": "--allow-incomplete",
    "xac1_unit_id": "--unit-id", "xac1_operator": "--operator", "xac1_station": "--station",
    "xac1_note": "--note", "xac1_junit": "--junit", "xac1_history": "--history",
    "xac1_no_history": "--no-history", "xac1_history_fleet": "--history-fleet",
}


def fleet_wanted(config: pytest.Config) -> bool:
    """Several ``--xac1-port``, a ``--xac1-ports`` file or a ``--xac1-report-dir``: the fleet's job."""
    return (len(config.getoption("xac1_port") or []) > 1 or bool(config.getoption("xac1_ports"))
            or bool(config.getoption("xac1_report_dir")))


def fleet_arguments(config: pytest.Config) -> argparse.Namespace:
    """The plugin's options as ``xac1 conformance``'s parsed arguments (what ``fleet.run`` takes)."""
    from .options import add_arguments

    parser = argparse.ArgumentParser(prog="xac1 conformance")
    add_arguments(parser)
    argv: list[str] = []
    for dest, flag in CLI_OPTION.items():
        value = config.getoption(dest)
        if value is None or value is False:
            continue
        for v in value if isinstance(value, list) else [value]:
            argv += [flag] if v is True else [flag, str(v)]
    if config.getoption("keyword"):
        argv += ["-k", config.getoption("keyword")]
    return parser.parse_args(argv)


def plugin_flags(text: str) -> str:
    """A fleet message with the plugin's option names (``--report-dir`` -> ``--xac1-report-dir``)."""
    import re

    names = {flag: "--xac1-" + flag[2:] for flag in CLI_OPTION.values()}
    return re.sub(r"(?<![\w-])--[a-z][a-z0-9-]*", lambda m: names.get(m.group(0), m.group(0)), text)


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config: pytest.Config) -> int | None:
    """Before pytest configures or collects anything: bad options end the run (exit 2); several devices
    hand the run over to the fleet (``conformance/fleet.py``), one ``xac1 conformance --port X`` process
    per device, exactly as the CLI route."""
    if not fleet_wanted(config):
        # Bad options exit 2 as in ``xac1 conformance`` (pytest's own usage error, 4, is our INCOMPLETE).
        problem = bad_options(config) if _options_used(config) else None
        if problem:
            print(f"ERROR: {problem}; nothing was sent", file=sys.stderr, flush=True)
            return 2
        return None
    from . import fleet

    args = fleet_arguments(config)
    try:
        fleet._check_options(args, fleet.targets(args))
    except fleet.FleetError as exc:
        print(f"xac1 plugin: {plugin_flags(str(exc))}; nothing was sent", file=sys.stderr, flush=True)
        return 2
    return fleet.run(args)


def _run(config: pytest.Config) -> Xac1Run | None:
    return config.stash.get(RUN_KEY, None)


def is_check(item: pytest.Item) -> bool:
    return _in_checks(item.path)


@functools.cache
def _in_checks(path: Path) -> bool:
    """The file at ``path`` lies below the checks' folder, links resolved; once a file, not once a test
    (the collection hooks ask for every item: over a thousand in a project's own suite)."""
    return CHECKS_DIR in path.resolve().parents


def pytest_configure(config: pytest.Config) -> None:
    for name, doc in MARKERS.items():
        config.addinivalue_line("markers", f"{name}: {doc}")
    run = Xac1Run(config)
    config.stash[RUN_KEY] = run
    if _options_used(config):
        _activate(run)


def _activate(run: Xac1Run) -> None:
    if run.active:
        return
    from xac1_proto.dut.settings import SettingsError

    c = run.config
    try:
        run.settings = _settings(c)
    except SettingsError as exc:
        raise pytest.UsageError(str(exc)) from None
    problem = check_outputs(c.getoption("xac1_report"), c.getoption("xac1_junit"), run.settings.flag)
    if problem:
        raise pytest.UsageError(problem)
    run.identity = {k: c.getoption(f"xac1_{k}") for k in ("unit_id", "operator", "station", "note")}
    run.command_line = c.getoption("xac1_command_line")
    from .stopping import StopPolicy

    run.policy = StopPolicy.shared("xac1 conformance" if run.settings.cli else "xac1 plugin")  # one a process
    if c.pluginmanager.get_plugin("terminalreporter") is None:
        from .progress import Progress

        run.progress = Progress()
    run.active = True


def _settings(c: pytest.Config) -> Any:
    from xac1_proto.dut.settings import Settings

    return Settings.make(_single_port(c), c.getoption("xac1_allow_motion"), c.getoption("xac1_fresh"),
                         c.getoption("xac1_safe_range"), seed=c.getoption("xac1_seed"),
                         examples=c.getoption("xac1_examples"), timeout=c.getoption("xac1_timeout"),
                         scratch_points=c.getoption("xac1_scratch_points"),
                         restore_mode0=c.getoption("xac1_restore_mode0"), cli=c.getoption("xac1_cli"),
                         readings=c.getoption("xac1_readings"))


def bad_options(c: pytest.Config) -> str | None:
    """What is wrong with the run's options (before anything is sent), else None."""
    from xac1_proto.dut.settings import SettingsError

    try:
        settings = _settings(c)
    except SettingsError as exc:
        return str(exc)
    return check_outputs(c.getoption("xac1_report"), c.getoption("xac1_junit"), settings.flag)


def check_outputs(report: str | None, junit: str | None, flag: Any) -> str | None:
    """Why an output file cannot be written (checked before anything is sent), else None."""
    from xac1_proto.output_file import OutputFileError, check_output

    from .report import kind_of

    for name, path, kinds in (("report", report, ("md", "html")), ("junit", junit, ("xml",))):
        if path is None:
            continue
        if not path:
            return f"{flag(name)} '': give the name of a file"
        p = Path(path)
        if kind_of(p) not in kinds:
            return f"{flag(name)} {path}: the name must end in {' or '.join('.' + k for k in kinds)}"
        parent = p.parent if str(p.parent) else Path(".")
        if p.is_dir():
            return f"{flag(name)} {path}: that is a directory; give a file name"
        if not parent.is_dir():
            return f"{flag(name)} {path}: the directory {parent} does not exist"
        if not os.access(parent, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
            return f"{flag(name)} {path}: not writable (permission denied)"
        try:  # through a link, to its target; never a FIFO or a device
            check_output(path, flag(name))
        except OutputFileError as exc:
            return str(exc)
    return None


def _order(item: pytest.Item) -> int:
    if item.get_closest_marker("xac1_fresh"):
        return 0
    if item.get_closest_marker("xac1_last"):
        return 2
    return 1


@pytest.hookimpl(tryfirst=True)
def pytest_collection(session: pytest.Session) -> None:
    """The session has started (pytest now always ends it with ``pytest_sessionfinish``): from here a
    signal's words say the device is restored and the report follows, as they then are."""
    run = _run(session.config)
    if run is not None and run.active and run.policy is not None:
        from .stopping import DURING_THE_RUN

        run.policy.what = DURING_THE_RUN


def pytest_collection_modifyitems(session: pytest.Session, config: pytest.Config,
                                  items: list[pytest.Item]) -> None:
    run = _run(config)
    checks = [i for i in items if is_check(i)]
    if run is None or not checks:
        return
    _activate(run)
    s = run.settings
    others = [i for i in items if not is_check(i)]
    checks.sort(key=_order)  # stable: file order within each group
    items[:] = checks + others
    for item in checks:
        if item.get_closest_marker("xac1_fresh") and not s.fresh:
            item.add_marker(pytest.mark.skip(
                reason=f"needs a device just powered on and never homed: pass {s.flag('fresh')}"))
        elif item.get_closest_marker("xac1_motion") and not s.motion:
            item.add_marker(pytest.mark.skip(
                reason=f"moves the actuator: pass {s.flag('allow-motion')} {s.flag('safe-range')} LO:HI"))


def pytest_deselected(items: list[pytest.Item]) -> None:
    checks = [i for i in items if is_check(i)]
    if not checks:
        return
    run = _run(checks[0].config)
    if run is not None:
        run.deselected += sum(1 for i in checks if not i.get_closest_marker("xac1_info"))


def pytest_collection_finish(session: pytest.Session) -> None:
    """Count the checks that will run (after -k): those the run never reaches are reported as not run."""
    run = _run(session.config)
    if run is None or not run.active:
        return
    checks = [i for i in session.items if is_check(i)]
    run.total = len(checks)
    run.total_info = sum(1 for i in checks if i.get_closest_marker("xac1_info"))
    run.collected = [(i.nodeid, i.name.removeprefix("test_"), i.get_closest_marker("xac1_info") is not None)
                     for i in checks]
    if checks and not _open_early(run):  # a port that does not open is known before the first check
        session.items[:] = [i for i in session.items if not is_check(i)]
        return
    if run.progress is not None:
        run.progress.begin(run.total, run.total_info)


def _open_early(run: Xac1Run) -> bool:
    """Open the device before the first check (the session fixture takes it); False, with the run's
    abort saying why, when the port does not open: no check is then started (nothing was sent)."""
    from xac1_proto.dut.device import DeviceUnderTest

    try:
        run.opened = DeviceUnderTest.open(run.settings)
    except Exception as exc:  # noqa: BLE001 - a port that does not open ends the run, with the reason
        run.abort = f"cannot open {run.settings.port}: {exc}"
        return False
    return True


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Any:
    run = _run(item.config)
    progress = run.progress if run is not None and is_check(item) else None
    if progress is not None:
        progress.check(Path(str(item.path)).stem.removeprefix("test_"), item.name.removeprefix("test_"))
    if run is not None and run.policy is not None and is_check(item):
        run.policy.raise_if_lost()  # a signal whose raise a check swallowed stops the run here
    try:
        return (yield)
    except KeyboardInterrupt:  # a signal (stopping.Interrupted) cut this check short: no verdict on it
        if run is not None and is_check(item) and item.nodeid not in run.interrupted:
            run.interrupted.append(item.nodeid)
        raise
    finally:
        if progress is not None:
            progress.finished_one()


# ---- fixtures ----

@pytest.fixture(scope="session")
def xac1_settings(request: pytest.FixtureRequest) -> Any:
    """The run's ``Settings`` (port, motion, safe range, fresh, seed)."""
    run = _run(request.config)
    assert run is not None
    _activate(run)
    return run.settings


@pytest.fixture(scope="session")
def xac1_device(request: pytest.FixtureRequest, xac1_settings: Any) -> Any:
    """The device under test, opened once; points and OUT ports snapshotted before any write and
    restored when the session ends."""
    from xac1_proto.dut.device import DeviceAbort, DeviceUnderTest, NoAnswer, PortLost, StoppedAnswering
    from xac1_proto.dut.safety import take_snapshot

    run = _run(request.config)
    assert run is not None
    dut, run.opened = run.opened, None  # opened before the first check (pytest_collection_finish)
    try:
        dut = dut or DeviceUnderTest.open(xac1_settings)
    except Exception as exc:  # noqa: BLE001 - a port that does not open ends the run, with the reason
        raise DeviceAbort(f"cannot open {xac1_settings.port}: {exc}") from None
    run.dut = dut
    dut.test = "(session start: snapshot)"
    try:
        run.snapshot = take_snapshot(dut)
    except (NoAnswer, StoppedAnswering, PortLost):
        raise  # the device or its port failed: THE DEVICE STOPPED ANSWERING, whatever the moment
    except DeviceAbort as exc:
        raise DeviceAbort(f"cannot take the safety snapshot: {exc}; nothing was written") from None
    yield dut
    _finish(run)


@pytest.fixture
def xac1_dut(request: pytest.FixtureRequest, xac1_device: Any) -> Any:
    """The device for one check: evidence is filed under the check, a latched alarm is reset first; when
    the check's last probe got no byte back, the liveness check follows at once (filed under the check)."""
    from xac1_proto.dut.device import StoppedAnswering

    dut = xac1_device
    dut.test = "(between checks: alarm reset)"
    dut.settle()
    dut.test = request.node.nodeid
    yield dut
    last = dut.log[-1] if dut.log else None
    try:
        if dut.gone is not None:  # found gone during the check, whatever the check made of it
            raise StoppedAnswering(dut.gone)
        if last is not None and last.test == dut.test and last.silent:
            dut.settle()  # StoppedAnswering when the device is gone: the check's verdict is taken back
    finally:
        dut.test = None


@pytest.fixture(scope="session")
def xac1_snapshot(request: pytest.FixtureRequest, xac1_device: Any) -> Any:
    """The points and OUT ports as they were before the run (``safety.Snapshot``)."""
    run = _run(request.config)
    assert run is not None
    return run.snapshot


@pytest.fixture(scope="session")
def xac1_kit(xac1_device: Any, xac1_snapshot: Any) -> Any:
    """Scratch points, safe positions and the shared sample exchanges (``kit.Kit``)."""
    from .kit import Kit

    return Kit(xac1_device, xac1_snapshot)


# ---- outcomes ----

@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Any:
    if not is_check(item):
        return (yield)
    from xac1_proto.dut.device import MotionRefused

    from .kit import NotEnoughPoints
    from .results import MANUAL_TAG, ManualStep

    try:
        return (yield)
    except MotionRefused as exc:
        pytest.skip(f"not moved: {exc}")
    except NotEnoughPoints as exc:
        pytest.skip(str(exc))
    except ManualStep as exc:
        pytest.skip(MANUAL_TAG + str(exc))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    report = yield
    run = _run(item.config)
    if run is None or not run.active or not is_check(item):
        return report
    from xac1_proto.dut.device import DeviceAbort

    if call.excinfo is not None and call.excinfo.errisinstance(DeviceAbort):
        run.cannot_go_on(item, report, call.excinfo)
        return report  # not a verdict on this check: the run stopped (the report says why)
    if report.when == "call" or (report.when == "setup" and not report.passed) or (
            report.when == "teardown" and report.failed):
        run.record(item, report, call)
    return report


def _finish(run: Xac1Run) -> None:
    """Restore the device once (every signal ignored meanwhile, and said so), then close it."""
    if run.restored or run.dut is None:
        return
    run.restored = True
    from xac1_proto.dut.safety import restore

    if run.policy is not None:
        run.policy.ending("the device is being restored; the report follows")
    try:
        run.dut.test = "(session end: restore)"
        run.dut.latched = None  # after an interruption nobody knows: the restore resets alarms first
        if run.snapshot is not None:
            _say(run, "xac1: restoring the device's points, OUT ports and position...")
            run.restore_report = restore(run.dut, run.snapshot)
    finally:
        with contextlib.suppress(Exception):  # a port that went away cannot close cleanly; nothing to lose
            run.dut.close()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """The run's end, whatever ended it: the device restored and closed, the reports written, the
    verdict and exit status decided and shown, the run recorded in the history store."""
    run = _run(session.config)
    if run is None or not run.active:
        return
    _end_on_the_device(run, exitstatus)
    from .report import build

    rep = build(run)
    c = session.config
    problems = _write_reports(c, rep)
    run.exit_status = session.exitstatus = _decide(run, rep, c)
    if run.progress is not None:
        _show_the_end(run, rep, c, problems)
    run.write_problems = problems
    target = _history_target(c)
    if target is not None:
        from .history import record_run

        record_run(run, rep, c, target)


def _end_on_the_device(run: Xac1Run, exitstatus: int) -> None:
    """Note what interrupted the run (even a signal whose raise a check swallowed), restore the device
    once and close whatever port is still open."""
    if run.policy is not None:
        run.policy.ending("the device is being restored; the report follows")
    stopped_by = run.policy.stopped_by if run.policy is not None else None  # even if its raise was lost
    if (exitstatus == pytest.ExitCode.INTERRUPTED or stopped_by) and not run.abort:
        run.interrupted_by = stopped_by or (run.policy.interrupted_by if run.policy is not None else None) \
            or "SIGINT"
        run.abort = f"interrupted ({run.interrupted_by}) before every check ran"
    if run.dut is not None and not run.restored:
        _finish(run)
    if run.opened is not None:  # opened, never used (every check left out or stopped before)
        with contextlib.suppress(Exception):
            run.opened.close()
        run.opened = None
    if run.interrupted_by is None and run.policy is not None and run.policy.interrupted_by:
        run.interrupted_by = run.policy.interrupted_by  # a signal during the restore: ignored, but said
    if run.policy is not None:  # the verdict is decided: a signal from now on cannot change it
        run.policy.ending("the verdict is decided; the report is being written and the verdict stands")


def _write_reports(c: pytest.Config, rep: Any) -> list[str]:
    """Write the report and JUnit files asked for; what could not be written."""
    from .report import write_file

    problems: list[str] = []
    for path, writer in ((c.getoption("xac1_report"), write_file), (c.getoption("xac1_junit"), _junit)):
        if path:
            try:
                writer(Path(path), rep)
            except (OSError, ValueError) as exc:  # ValueError: OutputFileError, it is no longer a file
                problems.append(f"could not write {path}: {getattr(exc, 'strerror', None) or exc}")
    return problems


def _decide(run: Xac1Run, rep: Any, c: pytest.Config) -> int:
    """The verdict line (kept on the run) and the exit status; a run that collected no check is NOT
    TESTED, exit 2 (as for bad options: pytest's own code for it, 5, says nothing)."""
    run.verdict_line = rep.verdict_line
    if run.total:
        return int(rep.exit_status(c.getoption("xac1_allow_incomplete")))
    select = c.getoption("keyword") or ""
    run.verdict_line = (f"NOT TESTED: -k {select!r} matches no check (names look like "
                        f"'framing', 'answer_length', 'read_back_after_write')" if select
                        else "NOT TESTED: no check was collected")
    return 2


def _show_the_end(run: Xac1Run, rep: Any, c: pytest.Config, problems: list[str]) -> None:
    """``xac1 conformance``'s last words (no pytest terminal): the summary, the verdict, the files."""
    from .report import terminal_lines

    lines = [] if run.total == 0 else terminal_lines(rep)[:-1]
    lines += [(f"could not write the report: {p}", "bad") for p in problems]
    lines.append((run.verdict_line or "", "good" if rep.accepted else "bad"))
    run.progress.lines(lines)
    for path in (c.getoption("xac1_report"), c.getoption("xac1_junit")):
        if path and not any(path in p for p in problems):
            run.progress.say(f"written: {path}")


def _history_target(c: pytest.Config) -> str | None:
    """The history store this run goes to (``--xac1-history``, ``XAC1_HISTORY``, the default), or None
    with ``--xac1-no-history``."""
    from xac1_proto.history.where import target

    return target(c.getoption("xac1_history"), c.getoption("xac1_no_history"))


def _junit(path: Path, rep: Any) -> None:
    from .junit import write_junit

    write_junit(path, rep)


def _say(run: Xac1Run, text: str) -> None:
    if run.progress is not None:
        run.progress.current = text.removeprefix("xac1: ")
        run.progress.say(text)
    else:
        print("\n" + text, flush=True)


def pytest_unconfigure(config: pytest.Config) -> None:
    run = _run(config)
    if run is not None and run.policy is not None:
        run.policy.uninstall()


def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    run = _run(config)
    if run is None or not run.active or not (run.results or run.abort or run.dut):
        return
    from .report import build, terminal_lines

    tr = terminalreporter
    tr.write_sep("=", "XA-C1 conformance")
    markup = {"": {}, "good": {"green": True, "bold": True}, "bad": {"red": True, "bold": True},
              "warn": {"yellow": True}, "bold": {"bold": True}}
    rep = build(run)
    for line, style in terminal_lines(rep):
        tr.write_line(line, **markup[style])
    for p in run.write_problems:
        tr.write_line(f"could not write the report: {p}", red=True)
    path = config.getoption("xac1_report")
    if path:
        tr.write_line(f"report written to {path}")
