"""The pytest plugin route gets the fleet too: ``pytest --xac1-port A --xac1-port B`` hands the run over
to ``conformance/fleet.py`` before collection (one ``xac1 conformance --port X`` process per device),
exactly as ``xac1 conformance --port A --port B`` does. Real simulators (one on TCP, one on a pty)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from test_fleet import MOTION, Sim, assert_restored, table_row

from conformance.fleet import CONFORMS, slug
from conformance.plugin import plugin_flags

pytestmark = pytest.mark.slow  # simulators and conformance processes

PLUGIN_MOTION = ["--xac1-" + a.removeprefix("--") if a.startswith("--") else a for a in MOTION]


@pytest.fixture
def sims(tmp_path: Path) -> Iterator[Callable[..., Sim]]:
    """Start simulators with ``start(name, *args, pty=...)`` (test_fleet's ``Sim``), stopped at the end."""
    started: list[Sim] = []

    def start(name: str, *extra: str, pty: bool = False) -> Sim:
        started.append(Sim(tmp_path, name, *extra, pty=pty))
        return started[-1]

    yield start
    for s in started:
        s.close()


def plugin(args: list[str], cwd: Path, timeout: float = 180) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--pyargs",
                           "conformance.checks", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.slow
def test_plugin_with_two_ports_runs_the_fleet(sims, tmp_path):
    """Two devices through the plugin: one process each, the fleet table, the per-device files and
    fleet pages, both devices restored, the fleet's exit status; pytest itself collected nothing."""
    tcp, pty = sims("tcp"), sims("pty", pty=True)
    out = tmp_path / "out"
    r = plugin(["--xac1-port", tcp.url, "--xac1-port", pty.url, *PLUGIN_MOTION,
                "--xac1-report-dir", str(out)], tmp_path)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert "Traceback" not in r.stdout + r.stderr
    assert "collected" not in r.stdout  # handed over before collection
    assert r.stdout.splitlines()[-1] == "xac1 conformance: fleet of 2: 2 CONFORMS (exit status 0)"
    for sim in (tcp, pty):
        assert f" {CONFORMS} " in table_row(r.stdout, sim.url)
        for suffix in (".html", ".xml", ".log"):
            assert (out / f"{slug(sim.url)}{suffix}").stat().st_size > 0
        # each child is a one-device `xac1 conformance` run of its own
        assert f"xac1 conformance: testing {sim.url}" in (out / f"{slug(sim.url)}.log").read_text()
        assert_restored(sim)
    assert (out / "fleet.html").read_text().count(">CONFORMS<") == 2


@pytest.mark.parametrize(("extra", "expected"), [
    (["--xac1-report", "r.html"], "--xac1-report names one file; with several ports use --xac1-report-dir"),
    (["twice"], "is listed twice: --xac1-port and --xac1-port"),
])
def test_plugin_fleet_bad_input_names_the_plugin_options(sims, tmp_path, extra, expected):
    """Bad fleet input through the plugin: exit 2, the message in the plugin's option names, nothing sent."""
    a = sims("a")
    b_url = a.url if extra == ["twice"] else sims("b").url
    before = a.host_bytes()
    r = plugin(["--xac1-port", a.url, "--xac1-port", b_url, *(x for x in extra if x != "twice")], tmp_path,
               timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert expected in r.stderr and "nothing was sent" in r.stderr, r.stderr
    assert a.host_bytes() == before


def test_plugin_flags_translates_only_known_options():
    """The fleet's hint translates the plugin's known options to their ``--xac1-`` names and leaves others
    alone."""
    assert plugin_flags("--report-dir DIR and --ports FILE, not --xac1-seed or --bogus") == (
        "--xac1-report-dir DIR and --xac1-ports FILE, not --xac1-seed or --bogus")


def test_plugin_bad_options_exit_2_before_anything_is_sent(sims, tmp_path):
    """One device, bad options: exit 2 as ``xac1 conformance`` gives (pytest's usage error would be 4,
    which is our INCOMPLETE), the message naming the option, nothing sent."""
    a = sims("a")
    before = a.host_bytes()
    for bad, expected in ((["--xac1-safe-range", "5:1"], "--xac1-safe-range: LO 0x000005 is above HI"),
                          (["--xac1-report", str(tmp_path / "no" / "r.html")], "does not exist")):
        r = plugin(["--xac1-port", a.url, *bad], tmp_path, timeout=60)
        assert r.returncode == 2, r.stdout + r.stderr
        assert expected in r.stderr and "nothing was sent" in r.stderr, r.stderr
    assert a.host_bytes() == before
