"""The fleet: ``xac1 conformance --port A --port B ...`` (or ``--ports FILE``) tests many devices at once.

How it works: one device's run is today's suite, unchanged: the fleet starts one
``xac1 conformance --port X ...`` child process per device (the same options, its own report, JUnit
file and log under ``--report-dir``), watches them, and gathers each result from three things the child
leaves: its exit status, its verdict line (the last line it prints) and its JUnit file (failed checks,
suite properties such as the firmware). A small pytest plugin loaded into each child
(``conformance.fleet_progress``) tells the fleet which check is running, for one live line per device.

Why a process per device and not pytest-xdist: xdist spreads the checks of ONE suite over workers,
whereas here each device needs the whole suite in order with its own session: its own safety snapshot
before the first write and restore at the end (docs/protocol.md "Behaviour the vendor text states":
the suite leaves a device as it found it), its own seed and settings, its own report. A process per
device isolates them completely: a device that stops answering, is unplugged, or a run that crashes or
hangs ends that child only; the others go on. Ctrl-C (or SIGTERM) reaches the fleet alone (the children
run in their own sessions, so the terminal's SIGINT does not hit them twice); the fleet forwards one
SIGINT to each child, which restores its own device exactly as a single run does, and waits for them
at most ``STOP_GRACE_S`` seconds before killing what is left (and saying which device may not be
restored).

Exit status, the worst device wins in the order 3 > 1 > 4 > 0: 3 when a device could not be tested
(named; nothing is known about it and it may be left unrestored, the most urgent to tell), 1 when one
does not conform (a known defect), 4 when one is incomplete (no defect found, not every check ran),
0 only when every device conforms. An interrupted fleet exits 2, as an interrupted single run does;
bad input (a port listed twice, a port that does not exist, a malformed ports file, an unwritable
--report-dir) exits 2 before anything is sent.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import hashlib
import json
import os
import re
import selectors
import shlex
import signal
import subprocess
import sys
import tempfile
import time
import uuid
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

STOP_GRACE_S: Final = 60.0  # after Ctrl-C: how long each child may take to restore its device
# Device verdicts of the fleet and the exit status each gives; RANK: worst first wins (3 > 1 > 4 > 0).
CONFORMS, NOT_CONFORM, INCOMPLETE, NOT_TESTED, INTERRUPTED = (
    "CONFORMS", "DOES NOT CONFORM", "INCOMPLETE", "NOT TESTED", "INTERRUPTED")
EXIT: Final = {CONFORMS: 0, NOT_CONFORM: 1, INCOMPLETE: 4, NOT_TESTED: 3, INTERRUPTED: 2}
RANK: Final = (NOT_TESTED, NOT_CONFORM, INCOMPLETE, CONFORMS)
FLEET_OWN: Final = frozenset({"port", "ports", "report_dir", "report_format", "report", "junit",
                               "history_fleet"})
PROGRESS_PLUGIN: Final = "conformance.fleet_progress"
MAX_STEM: Final = 96  # longest file stem made from a port URL (a hash of the URL ends a cut one)
_HASH_CHARS: Final = 12
_VERDICT = re.compile(r"^xac1 conformance: (.*) \(exit status (-?\d+)\)\s*$")
_FAILED = re.compile(r"^(?:FAIL|ERROR) (\S+): (.+)$")
_STOPPED = re.compile(r"^run stopped: (.+)$")
_UNSAFE = re.compile(r"^safety (?:PROBLEM|NOT RESTORED)\b.*$")  # the child's word that a restore failed
_FIRMWARE = (re.compile(r"^\s*firmware version: (\S+)"), re.compile(r"^(?:firmware|device) (\d{3}) on "))


class FleetError(Exception):
    """Bad input found before anything is sent (the message says what and where)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The fleet's own options, added to ``xac1 conformance``'s."""
    p.add_argument("--ports", metavar="FILE",
                   help="test every port listed in FILE at once (one URL a line, optionally followed by the "
                        "unit's id; # comments), each in its own process")
    p.add_argument("--report-dir", metavar="DIR",
                   help="with several ports: write DIR/<port>.html (or .md), DIR/<port>.xml (JUnit), "
                        "DIR/<port>.log and DIR/fleet.html, DIR/fleet.md")
    p.add_argument("--report-format", choices=("html", "md"), default="html",
                   help="with --report-dir: each device's report as html (default) or md")
    p.set_defaults(_conformance_parser=p)


def wanted(args: argparse.Namespace) -> bool:
    """True when the options ask for the fleet: several ports, a ports file, or a report directory."""
    return len(args.port or []) > 1 or bool(args.ports) or bool(args.report_dir)


# ---- the ports: where they come from, their names on disk, which are the same ----

@dataclass(frozen=True)
class Target:
    """One device to test: its URL, where it was named, the unit id the ports file gives (if any)."""

    url: str
    where: str  # "--port" or "FILE line N"
    unit: str | None = None


def read_ports_file(path: str) -> list[Target]:
    """``FILE``: one URL a line, optionally followed by the unit's id; blank lines and ``#`` comments."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise FleetError(f"--ports {path}: cannot read the ports file ({exc})") from None
    out = []
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        if len(words) > 2:
            raise FleetError(f"--ports {path} line {number}: expected a port URL and optionally a unit id, "
                             f"got {len(words)} words: {line.strip()!r}")
        out.append(Target(words[0], f"{path} line {number}", words[1] if len(words) == 2 else None))
    if not out:
        raise FleetError(f"--ports {path}: the file names no port (one URL a line, # comments)")
    return out


def slug(url: str) -> str:
    """A file name for a port: ``socket://127.0.0.1:4001`` -> ``socket-127.0.0.1-4001``; a long one is
    cut to ``MAX_STEM`` characters, ending with a hash of the whole URL (so two long URLs that differ
    only at their end still get two names): every file name stays far below the system's limit."""
    stem = re.sub(r"[^A-Za-z0-9._]+", "-", url).strip("-.") or "port"
    if len(stem) <= MAX_STEM:
        return stem
    digest = hashlib.sha256(url.encode("utf-8", "surrogateescape")).hexdigest()[:_HASH_CHARS]
    return f"{stem[:MAX_STEM - _HASH_CHARS - 1].rstrip('-.')}-{digest}"


def _resolve(url: str) -> str:
    """The port behind ``url`` for duplicate detection; FleetError when it does not exist."""
    import serial

    from xac1_proto import urlhandler  # noqa: F401  (registers xac1sim:// with pyserial)

    if "://" not in url:
        if not os.path.exists(url):
            raise FleetError("no such device")
        return os.path.realpath(url)
    scheme, _, rest = url.partition("://")
    scheme = scheme.lower()
    try:
        serial.serial_for_url(url, do_not_open=True)
    except (ValueError, serial.SerialException) as exc:
        raise FleetError(f"not a port URL pyserial knows ({exc})") from None
    if scheme == "hwgrep":
        from serial.tools import list_ports

        regex = rest.split("&", 1)[0]
        found = sorted(p.device for p in list_ports.grep(regex))
        if not found:
            raise FleetError(f"no serial port matches {regex!r} (xac1 ports lists them)")
        return os.path.realpath(found[0])
    if scheme in ("socket", "rfc2217"):
        host, _, port = rest.split("?", 1)[0].split("/", 1)[0].rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise FleetError("expected HOST:PORT with a port number 1..65535")
        return f"{scheme}://{host.lower()}:{int(port)}"
    return f"{scheme}://{rest}"


def targets(args: argparse.Namespace) -> list[Target]:
    """Every port named, checked: each exists (or is a well-formed URL) and none is named twice."""
    named = [Target(url, "--port") for url in args.port or []]
    if args.ports:
        named += read_ports_file(args.ports)
    seen: dict[str, Target] = {}
    for t in named:
        try:
            key = _resolve(t.url)
        except FleetError as exc:
            raise FleetError(f"port {t.url} ({t.where}): {exc}") from None
        if key in seen:
            first = seen[key]
            same = "" if first.url == t.url else f" (as {first.url})"
            raise FleetError(f"port {t.url} is listed twice: {first.where}{same} and {t.where}; "
                             f"each device runs once")
        seen[key] = t
    return named


def file_names(ts: Sequence[Target]) -> list[str]:
    """One distinct file stem a target (``slug``, ``-2``... appended when two slugs collide)."""
    out: list[str] = []
    for t in ts:
        stem, k = slug(t.url), 2
        while stem in out:
            stem, k = f"{slug(t.url)}-{k}", k + 1
        out.append(stem)
    return out


def check_names(folder: Path, stems: Sequence[str], suffixes: Sequence[str]) -> None:
    """FleetError when a device's file name would not fit in ``folder`` (checked before anything starts;
    ``slug`` keeps them short, so only a very deep folder can fail this)."""
    try:
        name_max = os.pathconf(folder, "PC_NAME_MAX")
        path_max = os.pathconf(folder, "PC_PATH_MAX")
    except (OSError, ValueError):  # the system does not say: the usual limits
        name_max, path_max = 255, 4096
    longest = max((f"{stem}{suffix}" for stem in stems for suffix in suffixes), key=len, default="")
    full = folder.resolve() / longest
    if len(longest.encode()) > name_max or len(str(full).encode()) >= path_max:
        raise FleetError(f"--report-dir {folder}: a device's file name would be too long there ({full}); "
                         f"choose a shorter folder")


def _writable_dir(path: str) -> Path:
    d = Path(path)
    try:
        d.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=d):
            pass
    except OSError as exc:
        raise FleetError(f"--report-dir {path}: cannot write there ({exc.strerror or exc})") from None
    return d


def _check_options(args: argparse.Namespace, ts: Sequence[Target]) -> None:
    """The options each child will get, checked once here (the same errors a single run gives)."""
    from xac1_proto.dut.settings import Settings, SettingsError

    for flag, value in (("--report", args.report), ("--junit", args.junit)):
        if value:
            raise FleetError(f"{flag} names one file; with several ports use --report-dir DIR "
                             f"(DIR/<port>.html, DIR/<port>.xml, DIR/fleet.html)")
    if getattr(args, "unit_id", None) and len(ts) > 1:
        raise FleetError("--unit-id names one unit; with several ports give each unit's id after its URL "
                         "in the --ports file")
    for t in ts:
        try:
            Settings.make(t.url, args.allow_motion, args.fresh, args.safe_range, args.seed, args.examples,
                          args.timeout, args.scratch_points, args.restore_mode0, cli=True)
        except SettingsError as exc:
            raise FleetError(str(exc).replace("--xac1-", "--")) from None


# ---- one device's child process ----

def passthrough(args: argparse.Namespace) -> list[str]:
    """The options given to ``xac1 conformance``, as a command line, without the fleet's own (each
    child gets its own port and files). Built from the parser, so every option reaches the children."""
    parser: argparse.ArgumentParser = args._conformance_parser
    out: list[str] = []
    for action in parser._actions:
        if not action.option_strings or action.dest in FLEET_OWN or action.dest == "help":
            continue
        value = getattr(args, action.dest, action.default)
        if value == action.default or value is None:
            continue
        flag = next((o for o in action.option_strings if o.startswith("--")), action.option_strings[0])
        if action.nargs == 0:
            out.append(flag)
        elif isinstance(value, list):
            for v in value:
                out += [flag, str(v)]
        else:
            out += [flag, str(value)]
    return out


def _supports(args: argparse.Namespace, flag: str) -> bool:
    return flag in args._conformance_parser._option_string_actions


@dataclass
class Device:
    """One device's run: the child, what it has said so far, and (once it ended) the gathered result."""

    target: Target
    stem: str
    report: Path | None
    junit: Path
    log: Path | None
    argv: list[str]
    proc: subprocess.Popen[bytes] | None = None
    t_start: float = 0.0
    t_end: float | None = None
    check: str = "starting"
    n: int = 0
    of: int = 0
    output: bytearray = field(default_factory=bytearray)
    _progress: bytes = b""
    streams: int = 0  # pipes still open
    # gathered at the end
    status: int | None = None
    verdict: str = ""
    verdict_line: str = ""
    reason: str = ""
    failed: list[tuple[str, str]] = field(default_factory=list)
    firmware: str | None = None
    unit: str | None = None
    killed: bool = False
    safety: list[str] = field(default_factory=list)  # the child's lines saying its restore failed

    @property
    def running(self) -> bool:
        return self.proc is not None and self.t_end is None

    def elapsed(self, now: float) -> float:
        return (self.t_end if self.t_end is not None else now) - self.t_start

    def progress(self, data: bytes) -> None:
        self._progress += data
        *lines, self._progress = self._progress.split(b"\n")
        for line in lines:
            try:
                event = json.loads(line)
            except ValueError:
                continue
            self.of = int(event.get("of", self.of))
            self.n = int(event.get("n", self.n))
            self.check = str(event.get("check") or event.get("state") or self.check)

    def state_text(self) -> str:
        if self.t_end is not None:
            return self.verdict or f"ended: {self.last_line()}"
        if self.n:
            return f"check {self.n}/{self.of or '?'}: {self.check}"
        return self.check

    def text(self) -> str:
        return self.output.decode("utf-8", "replace")

    def last_line(self) -> str:
        """The child's verdict line, or its exit status when it printed none."""
        lines = reversed(self.text().splitlines())
        found = (m.group(1) for line in lines if (m := _VERDICT.match(line)))
        return next(found, f"exit status {self.status}")


def _usb_serials() -> dict[str, str]:
    """Device path (resolved) -> USB serial number, for the ports pyserial enumerates."""
    try:
        from xac1_proto.cli.ports_cmd import enumerate_ports

        return {os.path.realpath(r.device): r.serial_number for r in enumerate_ports() if r.serial_number}
    except Exception:  # noqa: BLE001 - enumeration is a nicety for the table; never stop the fleet
        return {}


def gather(d: Device, interrupted: bool) -> None:
    """The device's verdict from its exit status, its verdict line and its JUnit file.

    In four steps: what the child printed (verdict line, FAIL lines, safety lines, why it stopped), what
    its JUnit file holds (properties, failed test cases), who the device is (firmware, unit id), and the
    verdict with its reason when the device could not be tested."""
    lines = d.text().splitlines()
    _read_output(d, lines)
    props, junit_failed = read_junit(d.junit)
    if not d.failed:
        d.failed = junit_failed
    _identify(d, lines, props)
    d.verdict = _verdict(d, interrupted)
    if d.killed:
        d.reason = (f"did not stop within {STOP_GRACE_S:g} s of the interrupt and was killed: its device "
                    f"may not be restored")
    elif d.verdict == NOT_TESTED and not d.reason:
        d.reason = _untested_reason(d.status, d.verdict_line)
    if d.verdict == NOT_TESTED and d.verdict_line:
        d.reason = _headed(d.reason, d.verdict_line)


def _read_output(d: Device, lines: Sequence[str]) -> None:
    """From the child's output: its last verdict line, its FAIL/ERROR lines, the lines saying a restore
    failed, and the reason it gave when the run stopped early."""
    d.verdict_line = next((m.group(1) for line in reversed(lines) if (m := _VERDICT.match(line))),
                          d.verdict_line)
    d.failed = [(m.group(1), m.group(2)) for line in lines if (m := _FAILED.match(line))]
    d.safety = [line.strip() for line in lines if _UNSAFE.match(line)]
    d.reason = next((m.group(1) for line in lines if (m := _STOPPED.match(line))), d.reason)


def read_junit(path: Path) -> tuple[dict[str, str], list[tuple[str, str]]]:
    """A JUnit file's suite properties and its failed or erroring test cases as (check, message), the
    ``test_`` prefix dropped; nothing when the file is missing or unreadable."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return {}, []
    props = {p.get("name", ""): p.get("value", "") for p in root.iter("property")
             if p.get("name") and p.get("value") is not None}
    failed = []
    for tc in root.iter("testcase"):
        bad = tc.find("failure")
        if bad is None:
            bad = tc.find("error")
        if bad is not None:
            name = tc.get("name", "?")
            failed.append((name.removeprefix("test_"), (bad.get("message") or "").strip()))
    return props, failed


def _identify(d: Device, lines: Sequence[str], props: dict[str, str]) -> None:
    """The firmware (JUnit property, else the child's summary) and the unit id (the ports file, else a
    JUnit property, else the USB serial number found before the run)."""
    d.firmware = props.get("firmware") or next(
        (m.group(1) for rx in _FIRMWARE for line in lines if (m := rx.match(line))), None)
    d.unit = (d.target.unit or props.get("unit-id") or props.get("unit_id") or props.get("unit")
              or props.get("serial") or d.unit)


def _verdict(d: Device, interrupted: bool) -> str:
    """The exit status read as a verdict; exit 1 counts as a defect only with a verdict line (without
    one the run crashed), exit 2 as an interrupt only when the fleet was interrupted."""
    status = d.status
    if d.killed:
        return NOT_TESTED
    if status == 0:
        return CONFORMS
    if status == 1 and d.verdict_line:
        return NOT_CONFORM
    if status == 4:
        return INCOMPLETE
    if status == 2 and interrupted:
        return INTERRUPTED
    return NOT_TESTED


def _untested_reason(status: int | None, verdict_line: str) -> str:
    """Why a device was not tested when its child gave no reason: a signal, its verdict's head, or no
    verdict at all."""
    head = verdict_line.split(":", 1)[0] if verdict_line else ""
    if status is not None and status < 0:
        return f"the run was killed by signal {-status}"
    if head:
        return f"{head} (exit status {status})"
    return f"the run ended without a verdict (exit status {status}); see its log"


def _headed(reason: str, verdict_line: str) -> str:
    """``reason`` led by the verdict line's head (``THE DEVICE STOPPED ANSWERING: ...``) unless it is."""
    head = verdict_line.split(":", 1)[0]
    return reason if reason.startswith(head) else f"{head}: {reason}"


def fleet_status(devices: Sequence[Device], interrupted: bool) -> int:
    if interrupted:
        return EXIT[INTERRUPTED]
    verdicts = {d.verdict for d in devices}
    return next((EXIT[v] for v in RANK if v in verdicts), 0)


# ---- the terminal ----

def _seconds(s: float) -> str:
    return f"{s:.1f} s"


def live_table(devices: Sequence[Device], now: float) -> Any:
    from rich.table import Table

    t = Table(show_header=True, header_style="bold", box=None, pad_edge=False)
    t.add_column("port", overflow="fold")
    t.add_column("state", overflow="fold")
    t.add_column("elapsed", justify="right", no_wrap=True)
    for d in devices:
        t.add_row(d.target.url, d.state_text(), _seconds(d.elapsed(now)))
    return t


def _failed_text(d: Device) -> str:
    if d.verdict == NOT_TESTED or (d.verdict == INTERRUPTED and not d.failed):
        text = d.reason
    else:
        text = ", ".join(name for name, _ in d.failed) or "-"
    return "; ".join([text, *d.safety]) if d.safety else text


def fleet_table(devices: Sequence[Device]) -> Any:
    from rich.table import Table

    t = Table(title="XA-C1 fleet", show_lines=False)
    for name in ("port", "unit", "firmware", "verdict", "failed checks", "duration"):
        t.add_column(name, overflow="fold", no_wrap=name in ("duration",))
    style = {CONFORMS: "green", NOT_CONFORM: "red bold", NOT_TESTED: "red bold", INCOMPLETE: "yellow",
             INTERRUPTED: "yellow"}
    for d in devices:
        t.add_row(d.target.url, d.unit or "-", d.firmware or "-",
                  f"[{style[d.verdict]}]{d.verdict}[/]{_restore_text(d)}", _failed_text(d),
                  _seconds(d.elapsed(d.t_end or 0.0)))
    return t


def _restore_text(d: Device) -> str:
    """The verdict cell's word that the device was left as the run left it (the child's safety lines)."""
    if any(line.startswith("safety PROBLEM") for line in d.safety):
        return " [red bold](RESTORE FAILED)[/]"
    if d.safety:
        return " [red bold](NOT RESTORED)[/]"
    return ""


def summary_line(devices: Sequence[Device], status: int) -> str:
    counts = [f"{sum(d.verdict == v for d in devices)} {v}" for v in (CONFORMS, NOT_CONFORM, INCOMPLETE,
                                                                       NOT_TESTED, INTERRUPTED)
              if any(d.verdict == v for d in devices)]
    untested = [d.target.url for d in devices if d.verdict == NOT_TESTED]
    named = f"; not tested: {', '.join(untested)}" if untested else ""
    return f"fleet of {len(devices)}: {', '.join(counts)}{named} (exit status {status})"


# ---- the pages ----

def write_pages(out_dir: Path, devices: Sequence[Device], status: int, started: _dt.datetime,
                command: str) -> list[Path]:
    from xac1_proto import __version__
    from xac1_proto.pages import render

    rows = [{
        "port": d.target.url, "unit": d.unit, "firmware": d.firmware, "verdict": d.verdict,
        "verdict_line": d.verdict_line, "reason": d.reason, "failed": d.failed, "safety": d.safety,
        "duration": _seconds(d.elapsed(d.t_end or 0.0)), "status": d.status,
        "report": d.report.name if d.report else None, "junit": d.junit.name,
        "log": d.log.name if d.log else None,
    } for d in devices]
    ctx = {"title": "XA-C1 fleet conformance", "devices": rows, "status": status,
           "summary": summary_line(devices, status), "started": started.strftime("%Y-%m-%d %H:%M:%S %Z"),
           "command": command, "version": __version__, "worst": next((v for v in RANK if any(
               d.verdict == v for d in devices)), CONFORMS)}
    out = []
    for name in ("fleet.html", "fleet.md"):
        path = out_dir / name
        path.write_text(render(f"{name}.j2", **ctx), encoding="utf-8")
        out.append(path)
    return out


# ---- running it ----

class _Stop:
    """SIGINT/SIGTERM while the fleet runs: remembered, forwarded once to every child by the loop."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.repeated = False

    def __call__(self, signum: int, frame: object) -> None:
        if self.signum is not None:
            self.repeated = True
        self.signum = signum

    @contextlib.contextmanager
    def installed(self) -> Iterator[None]:
        import threading

        if threading.current_thread() is not threading.main_thread():
            yield
            return
        old = {s: signal.signal(s, self) for s in (signal.SIGINT, signal.SIGTERM)}
        from xac1_proto.signals import taking_over

        taking_over()  # after this, the dispatcher ignores signals while the fleet's results are said
        try:
            yield
        finally:
            for s, h in old.items():
                signal.signal(s, h)


def _start(d: Device, sel: selectors.BaseSelector) -> None:
    for old in (d.junit, d.report):  # a file left by an earlier run must not pass for this run's
        if old is not None:
            old.unlink(missing_ok=True)
    read_fd, write_fd = os.pipe()
    env = dict(os.environ)
    env["PYTEST_PLUGINS"] = ",".join(p for p in (env.get("PYTEST_PLUGINS"), PROGRESS_PLUGIN) if p)
    env["XAC1_FLEET_PROGRESS_FD"] = str(write_fd)
    try:
        d.proc = subprocess.Popen(d.argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, pass_fds=(write_fd,), env=env,
                                  start_new_session=True)
    finally:
        os.close(write_fd)
    d.t_start = time.monotonic()
    assert d.proc.stdout is not None
    os.set_blocking(read_fd, False)
    sel.register(d.proc.stdout, selectors.EVENT_READ, (d, "out"))
    sel.register(read_fd, selectors.EVENT_READ, (d, "progress"))
    d.streams = 2


def _pump(sel: selectors.BaseSelector, wait: float) -> None:
    for key, _ in sel.select(timeout=wait):
        d, kind = key.data
        try:
            data = os.read(key.fd, 65536)
        except BlockingIOError:
            continue
        except OSError:
            data = b""
        if not data:
            sel.unregister(key.fileobj)
            if kind == "progress":
                os.close(key.fd)
            d.streams -= 1
        elif kind == "out":
            d.output += data
        else:
            d.progress(data)


def run(args: argparse.Namespace) -> int:
    """Test every named device at once; the exit status of the worst (see the module docstring)."""
    try:
        ts = targets(args)
        _check_options(args, ts)
        out_dir = _writable_dir(args.report_dir) if args.report_dir else None
    except FleetError as exc:
        print(f"xac1 conformance: {exc}", file=sys.stderr)
        return 2
    from rich.console import Console

    console = Console(highlight=False)
    if not console.is_terminal:
        console = Console(highlight=False, width=max(console.width, 160))
    started = _dt.datetime.now().astimezone()
    common = passthrough(args)
    fleet_id = uuid.uuid4().hex  # each child records its unit in the history with it
    with contextlib.ExitStack() as stack:
        files = out_dir or Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="xac1-fleet-")))
        try:
            check_names(files, file_names(ts), (f".{args.report_format}", ".xml", ".log"))
        except FleetError as exc:
            print(f"xac1 conformance: {exc}", file=sys.stderr)
            return 2
        devices = [_device(args, t, stem, files, out_dir, common, fleet_id)
                   for t, stem in zip(ts, file_names(ts), strict=True)]
        _name_usb_units(devices)
        interrupted = _Watch(devices, console, _Stop()).run()
        for d in devices:
            if d.log:
                d.log.write_bytes(bytes(d.output))
            gather(d, interrupted)
        status = fleet_status(devices, interrupted)
        console.print(fleet_table(devices))
        for d in devices:
            for check, rule in d.failed if d.verdict == NOT_CONFORM else []:
                console.print(f"  {d.target.url}: FAIL {check}: {rule}", markup=False)
        if out_dir:
            pages = write_pages(out_dir, devices, status, started, _fleet_command(args, ts, common))
            console.print(f"reports: {', '.join(str(p) for p in pages)} and one .{args.report_format}, .xml, "
                          f".log a device in {out_dir}", markup=False)
        if interrupted:
            console.print("xac1 conformance: interrupted: every device was asked to stop and restore itself; "
                          "see each device's verdict above", markup=False)
        if not getattr(args, "no_history", True):
            console.print(f"xac1 conformance: history: each device's run is recorded with fleet id "
                          f"{fleet_id} (xac1 history list --fleet {fleet_id})", markup=False)
        console.print(f"xac1 conformance: {summary_line(devices, status)}", markup=False)
    return status


def _fleet_command(args: argparse.Namespace, ts: Sequence[Target], common: list[str]) -> str:
    """The command line that repeats this fleet run, for its pages."""
    ports = [a for t in ts if t.where == "--port" for a in ("--port", t.url)]
    ports += ["--ports", args.ports] if args.ports else []
    return shlex.join(["xac1", "conformance", *ports, *common, "--report-dir", str(args.report_dir)])


def _device(args: argparse.Namespace, t: Target, stem: str, files: Path, out_dir: Path | None,
            common: list[str], fleet_id: str) -> Device:
    """One device's child run: its command line and the files it writes (the report and log only
    when kept in a report directory; the JUnit file always, the fleet reads its verdicts there). The
    unit id (from a ports file) and the fleet id go to a plugin that knows them."""
    report = files / f"{stem}.{args.report_format}" if out_dir else None
    junit = files / f"{stem}.xml"
    argv = [sys.executable, "-m", "xac1_proto", "conformance", "--port", t.url, *common,
            "--junitxml", str(junit)]
    argv += ["--report", str(report)] if report else []
    argv += ["--unit-id", t.unit] if t.unit and _supports(args, "--unit-id") else []
    argv += ["--history-fleet", fleet_id] if _supports(args, "--history-fleet") else []
    return Device(t, stem, report, junit, files / f"{stem}.log" if out_dir else None, argv)


def _name_usb_units(devices: Sequence[Device]) -> None:
    """Name each device on a local serial port by its USB adapter's serial number, when it has one."""
    serials = _usb_serials()
    for d in devices:
        if "://" not in d.target.url or d.target.url.lower().startswith("hwgrep://"):
            with contextlib.suppress(FleetError):
                d.unit = serials.get(_resolve(d.target.url))


class _Watch:
    """The children from start to end: their progress shown (a live table on a terminal, a line a
    device otherwise), a stop forwarded once to each, and whoever still runs STOP_GRACE_S later killed."""

    def __init__(self, devices: Sequence[Device], console: Any, stop: _Stop) -> None:
        from rich.live import Live

        self.devices, self.console, self.stop = devices, console, stop
        self.forwarded_at: float | None = None
        self.told_repeat = False
        self.live = Live(live_table(devices, time.monotonic()), console=console, refresh_per_second=4,
                         transient=False) if console.is_terminal else None

    def run(self) -> bool:
        """Start every child, show their progress until all have ended; True when interrupted."""
        sel = selectors.DefaultSelector()
        with self.stop.installed(), (self.live or contextlib.nullcontext()):
            for d in self.devices:
                _start(d, sel)
                self._say(f"{d.target.url}: started ({d.stem})")
            while any(d.running for d in self.devices):
                _pump(sel, 0.1)
                now = time.monotonic()
                self._note_the_ended(now)
                self._pass_on_a_stop(now)
                self._kill_after_the_grace(now)
                if self.live is not None:
                    self.live.update(live_table(self.devices, now))
        sel.close()
        return self.stop.signum is not None

    def _say(self, line: str) -> None:
        """A line for a console without the live table (the table shows it otherwise)."""
        if self.live is None:
            self.console.print(line, markup=False)

    def _note_the_ended(self, now: float) -> None:
        """Each child whose process has ended and whose output is all read: its end time and status."""
        for d in self.devices:
            if d.running and d.streams == 0 and d.proc is not None and d.proc.poll() is not None:
                d.t_end, d.status = now, d.proc.returncode
                self._say(f"{d.target.url}: {d.last_line()} ({_seconds(d.elapsed(now))})")

    def _pass_on_a_stop(self, now: float) -> None:
        """The fleet's first SIGINT/SIGTERM forwarded once to every child as SIGINT (each restores its
        device); a repeated one answered with a line, nothing more."""
        if self.stop.signum is not None and self.forwarded_at is None:
            self.forwarded_at = now
            self.console.print("xac1 conformance: stopping: each device finishes its restore "
                               f"(at most {STOP_GRACE_S:g} s)", markup=False)
            for d in self.devices:
                if d.running and d.proc is not None:
                    with contextlib.suppress(ProcessLookupError):
                        d.proc.send_signal(signal.SIGINT)
        if self.stop.repeated and not self.told_repeat:
            self.told_repeat = True
            self.console.print("xac1 conformance: still waiting for the devices to be restored", markup=False)

    def _kill_after_the_grace(self, now: float) -> None:
        """STOP_GRACE_S after the stop was forwarded, kill every child still running (once)."""
        if self.forwarded_at is not None and now - self.forwarded_at > STOP_GRACE_S:
            for d in self.devices:
                if d.running and d.proc is not None:
                    d.killed = True
                    d.proc.kill()
            self.forwarded_at = float("inf")
