"""What every test module shares: Debian-tool requirements, hypothesis profiles, waiting on something
observable, and the ways tests run ``xac1`` and read a device back.

How this works:
- A test that shells out to a Debian tool carries ``@pytest.mark.requires_tool("socat")`` (several
  names allowed; ``require_tool`` does the same inside a test). A missing tool SKIPS the test with a
  reason naming the Debian package, or FAILS it when the environment variable ``CI`` is set (any value
  but empty, ``0`` or ``false``): CI never skips a test silently.
- Hypothesis profiles ``ci`` (derandomized, no deadline, no example database, failing blobs printed,
  every test's full budget) and ``dev`` (random, a database in ``.hypothesis/``, no deadline either:
  timing varies with load; a tenth of each budget, for the inner loop) are registered here;
  ``HYPOTHESIS_PROFILE`` or ``--hypothesis-profile`` picks one, else ``ci`` under CI and ``dev``
  otherwise. A test with its own budget writes ``@settings(max_examples=budget(N))``.
- ``wait_until(predicate, timeout, what)`` replaces sleeping as synchronisation: it polls something the
  test can observe and fails saying what never happened.
- The test session and the processes its tests start cache their compiled modules, whatever
  ``PYTHONDONTWRITEBYTECODE`` says.
- ``gallery`` is ``captures/make_gallery.py`` (the scripted session, the capture makers).
- ``xac1(...)`` runs the console script's module as a user does (a real subprocess);
  ``conformance(...)`` runs ``xac1 conformance`` (``failed_checks``/``skipped_checks`` read its JUnit
  XML); ``read_table(url)`` reads a device's 15 points and its OUT ports through a plain client.

Plain helpers are imported by the test modules (``from conftest import xac1``): pytest puts this
directory on ``sys.path`` (rootdir-relative "prepend" import mode, as for ``sniffer_wire`` and
``strategies``).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TypeVar

import pytest
from hypothesis import settings

from xac1_proto import spec
from xac1_proto.client import Client

ROOT = Path(__file__).resolve().parent.parent
CAPTURES = ROOT / "captures"

# Every process a test starts (xac1, pytest, the conformance suite) runs as an installed tool does, its
# compiled modules cached: where the environment forbids writing them (PYTHONDONTWRITEBYTECODE), each of
# the suite's hundreds of children would compile the package and have pytest rewrite the asserts of every
# plugin's modules (hypothesis, anyio, xdist) again, doubling the CPU time of a conformance run.
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
# The test session alike: pytest compiles each test module with its asserts rewritten, and caches the result
# only where bytecode may be written; with PYTHONDONTWRITEBYTECODE every worker would rewrite and compile all
# hundred-odd test modules again on every run (seconds of each worker's start). This file is imported before
# any test module is collected.
sys.dont_write_bytecode = False


def _load_gallery() -> ModuleType:
    """``captures/make_gallery.py`` (not a package module): the scripted session and capture makers."""
    spec_ = importlib.util.spec_from_file_location("make_gallery", CAPTURES / "make_gallery.py")
    assert spec_ is not None and spec_.loader is not None
    module = importlib.util.module_from_spec(spec_)
    spec_.loader.exec_module(module)
    return module


gallery = _load_gallery()

pytest_plugins = ("pytester",)  # tests/test_conftest.py runs small pytest sessions with it

# ---- Debian tools ----

# tool -> the Debian package that installs it (.ci/run installs the same list)
TOOL_PACKAGES = {
    "socat": "socat",
    "tshark": "tshark",
    "editcap": "wireshark-common",
    "sigrok-cli": "sigrok-cli",
    "jpnevulator": "jpnevulator",
    "chromium": "chromium",
}


def in_ci() -> bool:
    """``CI`` is set (GitHub, GitLab and most CI services set ``CI=true``)."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def missing_tools(tools: list[str] | tuple[str, ...]) -> str | None:
    """What is missing of ``tools`` and the Debian packages that install it, or None if nothing is."""
    unknown = [t for t in tools if t not in TOOL_PACKAGES]
    if unknown:
        raise ValueError(f"requires_tool: no Debian package known for {', '.join(unknown)} "
                         f"(known: {', '.join(TOOL_PACKAGES)}); add it to TOOL_PACKAGES in tests/conftest.py")
    missing = [t for t in tools if shutil.which(t) is None]
    if not missing:
        return None
    packages = sorted({TOOL_PACKAGES[t] for t in missing})
    return (f"{', '.join(missing)} not found on PATH "
            f"(Debian package {', '.join(packages)}: sudo apt-get install {' '.join(packages)})")


def require_tool(*tools: str) -> None:
    """Skip the running test when a tool is not on PATH (fail it instead under CI), naming the package."""
    what = missing_tools(tools)
    if what is None:
        return
    if in_ci():
        pytest.fail(f"{what}; CI is set, so this test fails instead of being skipped", pytrace=False)
    pytest.skip(what)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "requires_tool(*names): the test runs these Debian tools; skipped when one is missing "
                   "(failed when CI is set), the reason naming the package")


# ---- workers ----

def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """How many workers ``-n auto`` starts: a core each and one more. Every test waits on something in
    real time at some point (an xac1 process, a conformance run, a timeout, a pace, chromium, tshark:
    half of a slow test's time, a quarter of an in-process one's), and the one more runs meanwhile; more
    would add their start-up and collection to the CPU, and load enough to crowd the tests that measure
    time. None (xdist's own count) when ``PYTEST_XDIST_AUTO_NUM_WORKERS`` says how many."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return cores + 1


def _required_tools(item: pytest.Item) -> list[str]:
    return [tool for mark in item.iter_markers("requires_tool") for tool in mark.args]


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Outside CI a test whose tool is missing is marked skipped (before its fixtures start anything;
    the skip is reported at the test). An unknown tool name is left for the call to report."""
    if in_ci():
        return
    for item in items:
        try:
            what = missing_tools(_required_tools(item))
        except ValueError:
            continue
        if what is not None:
            item.add_marker(pytest.mark.skip(reason=what))


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_call(item: pytest.Item) -> None:
    """Under CI a missing tool fails the test here; an unknown tool name fails it anywhere."""
    require_tool(*_required_tools(item))


# ---- the history store ----

@pytest.fixture(scope="session")
def session_data_home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("xdg-data")


@pytest.fixture(autouse=True)
def data_home(session_data_home: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Every test (and every process it starts) records runs under this session's temporary data folder,
    never the user's: XDG_DATA_HOME points there, XAC1_HISTORY is unset. One folder a session (a worker),
    so its history store is made once; a test that reads the default store asks for ``private_history``."""
    monkeypatch.setenv("XDG_DATA_HOME", str(session_data_home))
    monkeypatch.delenv("XAC1_HISTORY", raising=False)
    return session_data_home


@pytest.fixture
def private_history(data_home: Path, tmp_path_factory: pytest.TempPathFactory,
                    monkeypatch: pytest.MonkeyPatch) -> Path:
    """A data folder of this test's own: a default history store and spool no other test writes."""
    folder = tmp_path_factory.mktemp("xdg-data-private")
    monkeypatch.setenv("XDG_DATA_HOME", str(folder))
    return folder


@pytest.fixture(scope="session")
def postgres() -> Iterator[object]:
    """One real PostgreSQL server for the session (``tests/postgres_server.py``), started on first use;
    skipped naming the Debian package when PostgreSQL is not installed (failed under CI)."""
    import postgres_server

    why = postgres_server.missing()
    if why is not None:
        if in_ci():
            pytest.fail(f"{why}; CI is set, so this test fails instead of being skipped", pytrace=False)
        pytest.skip(why)
    with postgres_server.running() as server:
        yield server


# ---- Hypothesis ----

def hypothesis_profile() -> str:
    """The profile this run uses: ``HYPOTHESIS_PROFILE``, else ``ci`` under CI, else ``dev``."""
    return os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if in_ci() else "dev")


# Both on hypothesis's own defaults (newer hypothesis loads a built-in "ci" profile by itself under CI,
# and a profile's parent is otherwise whatever is loaded).
# ``ci`` runs every test's full budget; ``dev`` (the inner loop) a tenth of it: hypothesis's default of
# 100 examples becomes 10, and ``budget(N)`` scales a test's own budget alike.
FULL_EXAMPLES = settings.get_profile("default").max_examples
settings.register_profile("ci", settings.get_profile("default"), derandomize=True, deadline=None,
                          database=None, print_blob=True)
settings.register_profile("dev", settings.get_profile("default"), derandomize=False, deadline=None,
                          print_blob=False, max_examples=FULL_EXAMPLES // 10)
settings.load_profile(hypothesis_profile())


def budget(full: int) -> int:
    """A test's hypothesis budget: ``full`` examples under a profile of the full default budget (``ci``,
    ``--hypothesis-profile ci``), scaled as the loaded profile scales the default otherwise (``dev``: a
    tenth), never fewer than the profile's own ``max_examples`` nor more than ``full``. Called where the
    test is decorated, so after ``--hypothesis-profile`` has been applied."""
    current = settings().max_examples
    return min(full, max(current, full * current // FULL_EXAMPLES))


# ---- waiting ----

T = TypeVar("T")


def wait_until(predicate: Callable[[], T], timeout: float, what: str, interval: float = 0.01) -> T:
    """Poll ``predicate`` until it returns something truthy and return that; after ``timeout`` seconds
    fail with ``what`` (what the test was waiting for) and the last value seen."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"waited {timeout} s for {what}; it never happened (last: {value!r})")
        time.sleep(interval)


# ---- running xac1 ----

RUN_TIMEOUT = 90.0  # seconds: a run that hangs fails its test instead of hanging the session


def xac1(*args: str, cwd: str | os.PathLike[str] = ROOT, timeout: float = 60.0,
         stdin: str = "") -> subprocess.CompletedProcess[str]:
    """``xac1 ARGS`` as a user runs it (``python -m xac1_proto``), output captured as text; ``stdin``
    is all it reads (then end of file: never the terminal pytest runs in)."""
    return subprocess.run([sys.executable, "-m", "xac1_proto", *args], cwd=cwd, input=stdin,
                          capture_output=True, text=True, timeout=timeout)


@contextlib.contextmanager
def xac1_sim(*args: str, preexec_fn: Callable[[], object] | None = None,
             timeout: float = 5.0) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """Run ``xac1 sim ARGS``; yields the process and its first stdout line (where to connect). On the
    way out: SIGTERM (the orderly end), then kill after ``timeout``."""
    proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "sim", *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=preexec_fn)
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline().strip()
        assert first, proc.stderr.read() if proc.stderr else ""
        yield proc, first
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        for f in (proc.stdin, proc.stdout, proc.stderr):
            if f is not None:
                f.close()


def conformance(args: list[str], cwd: str | os.PathLike[str],
                timeout: float = RUN_TIMEOUT) -> subprocess.CompletedProcess[str]:
    """``xac1 conformance ARGS`` in ``cwd``."""
    return xac1("conformance", *args, cwd=cwd, timeout=timeout)


def failed_checks(junit: Path) -> set[str]:
    """Names of the checks that failed (or errored) in a run's JUnit XML."""
    root = ET.parse(junit).getroot()
    return {case.get("name", "") for case in root.iter("testcase")
            if case.find("failure") is not None or case.find("error") is not None}


def skipped_checks(junit: Path) -> dict[str, str]:
    """Skipped check name -> the reason given, from a run's JUnit XML."""
    root = ET.parse(junit).getroot()
    return {case.get("name", ""): skip.get("message", "") for case in root.iter("testcase")
            if (skip := case.find("skipped")) is not None}


@dataclass(frozen=True)
class DeviceTable:
    """Every point's (V, A, O, Pos) by number 1-F, and the OUT ports."""

    points: dict[int, tuple[int, int, int, int]]
    outputs: int


def read_table(url: str) -> DeviceTable:
    """The device's points (every N 0RP takes) and OUT ports, read through a separate plain client."""
    first, last = spec.FIELDS["n"].range_for(spec.COMMAND)
    with Client(url, timeout=2) as c:
        points = {n: (a.v, a.a, a.o, a.pos) for n in range(first, last + 1) for a in [c.read_point(n)]}
        return DeviceTable(points, c.read_outputs().o)
