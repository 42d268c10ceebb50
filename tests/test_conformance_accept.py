"""Acceptance a QA lead can sign: no partial run is called an acceptance, a silent device is judged fast,
the report and JUnit are tied to the unit, bad output paths and a -k that matches nothing are refused
in our words before anything is sent, and a device that vanishes ends the run with exit 3.

Each run is ``xac1 conformance`` in a subprocess against ``xac1 sim --tcp`` (a separate process, as a
device would be) or the simulator served over TCP in this process.
"""

from __future__ import annotations

import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import pytest

from xac1_proto.sim import SimConfig, serve_tcp

pytestmark = pytest.mark.slow  # whole conformance runs as processes

RUN_TIMEOUT = 120
MOTION = ["--allow-motion", "--safe-range", "0:0x1000"]
NOISE = ("Traceback", "KeyboardInterrupt", "site-packages", "! Interrupted", "b'", "error in ")


def conformance(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "xac1_proto", "conformance", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=RUN_TIMEOUT)


def quiet(r: subprocess.CompletedProcess) -> None:
    out = r.stdout + r.stderr
    for noise in NOISE:
        assert noise not in out, (noise, out[-3000:])


@pytest.fixture
def sim_process(request) -> Iterator[tuple[str, subprocess.Popen]]:
    """`xac1 sim --tcp` in its own process (extra options as the indirect parameter)."""
    extra = list(getattr(request, "param", []))
    command = [sys.executable, "-m", "xac1_proto", "sim", "--tcp", "127.0.0.1:0", "--time-scale", "0", *extra]
    proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True)
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("socket://"), url
        yield url, proc
    finally:
        if proc.poll() is None:
            proc.stdin.close()
            proc.terminate()
        proc.wait(timeout=10)
        proc.stdout.close()


def test_partial_run_is_incomplete_not_conforms(sim_process, tmp_path):
    """The issue's case: motion allowed, no scratch points, so most checks cannot run. The verdict is
    INCOMPLETE naming the option that would run them, exit 4; --allow-incomplete makes the exit 0 and
    the verdict stays INCOMPLETE. Never CONFORMS."""
    url, _ = sim_process
    r = conformance(["--port", url, *MOTION], tmp_path)
    last = r.stdout.splitlines()[-1]
    assert r.returncode == 4, r.stdout[-3000:]
    assert "INCOMPLETE: 69 of 97 checks not run; to run them: --fresh, --scratch-points 1,2,3,4" in last, last
    assert "CONFORMS" not in r.stdout
    quiet(r)
    r2 = conformance(["--port", url, *MOTION, "--allow-incomplete"], tmp_path)
    assert r2.returncode == 0 and "INCOMPLETE: 69 of 97 checks not run" in r2.stdout.splitlines()[-1]


def test_manual_step_is_listed_not_missing(sim_process, tmp_path):
    """On a real line the emergency stop cannot be pressed by the suite: the check is a manual step
    (what to do, what to see), listed in the report, and does not keep the verdict from CONFORMS."""
    url, _ = sim_process
    report = tmp_path / "r.md"
    r = conformance(["--port", url, *MOTION, "--fresh", "--scratch-points", "1,2,3,4", "--report",
                     str(report), "--examples", "5"], tmp_path)
    last = r.stdout.splitlines()[-1]
    assert r.returncode == 0, r.stdout[-3000:]
    assert "CONFORMS: 97 passed, 0 failed (of 97 checks of stated rules); 1 manual step(s)" in last, last
    text = report.read_text()
    assert "## Manual steps" in text and "press the emergency stop" in text and "0%%0E" in text


@pytest.mark.parametrize("sim_process", [["--deviation", "silent-on-malformed"]], indirect=True,
                         ids=["silent-on-malformed"])
def test_device_silent_to_malformed_commands_is_judged_within_a_minute(sim_process, tmp_path):
    """A device that stays silent on malformed commands: every such check fails in about the answer
    timeout, the whole run stays under a minute, progress lines show where it is, and each failure says
    what was expected and what came back."""
    url, _ = sim_process
    junit = tmp_path / "j.xml"
    start = time.monotonic()
    r = conformance(["--port", url, *MOTION, "--scratch-points", "1,2,3,4", "--junit", str(junit)], tmp_path)
    took = time.monotonic() - start
    assert r.returncode == 1, r.stdout[-3000:]
    assert took < 60, took
    assert "xac1 conformance: [" in r.stdout and "] malformed (check" in r.stdout
    messages = [f.get("message", "") for f in ET.parse(junit).getroot().iter("failure")]
    malformed = [m for m in messages if "0RP with N = 0" in m]
    assert malformed == ["0RP with N = 0 (0RP takes 1-F) ('0RP0' CR LF): expected an alarm answer 0%%Ec, "
                         "received no answer (silence) within 1 s"], messages
    quiet(r)


def test_report_and_junit_are_tied_to_the_unit(tmp_path):
    """The report carries the unit id, operator, station, note and the command line, a summary by rule
    group before the verdict table, failures first; JUnit counts only stated-rule checks as tests, with
    the device, port, seed and kit version as properties and the exchanges as system-out."""
    report, junit = tmp_path / "r.html", tmp_path / "j.xml"
    with serve_tcp(SimConfig(time_scale=0, deviations=frozenset({"wrong-n"}))) as sim:
        r = conformance(["--port", sim.url, *MOTION, "--scratch-points", "1,2,3,4", "--fresh", "--unit-id",
                         "SN-0042", "--operator", "A. Tester", "--station", "rack 3 <slot 2>", "--note",
                         "after repair", "--report", str(report), "--junit", str(junit), "--examples", "3"],
                        tmp_path)
    assert r.returncode == 1, r.stdout[-3000:]
    page = report.read_text()
    for part in ("SN-0042", "A. Tester", "rack 3 &lt;slot 2&gt;", "after repair", "--unit-id SN-0042"):
        assert part in page, part
    assert page.index("Summary by rule group") < page.index("Verdicts (failures first)")
    table = page.split("Verdicts (failures first)")[1]
    assert table.index(">FAIL<") < table.index(">PASS<")
    assert "0RPN answered" not in page and "expected N=1 in the answer, received N=2" in page
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite is not None
    assert suite.get("name") == f"XA-C1 100 on {sim.url}"
    props = {p.get("name"): p.get("value") for p in suite.find("properties")}
    assert props["firmware"] == "100" and props["port"] == sim.url and props["seed"] == "0"
    assert props["kit version"].startswith("xac1-proto ") and props["unit id"] == "SN-0042"
    assert any(k.startswith("information: ") for k in props)
    cases = suite.findall("testcase")
    assert int(suite.get("tests")) == 98 and len(cases) == 98  # information records are not tests
    failed = [c for c in cases if c.find("failure") is not None]
    assert failed and all(c.find("system-out") is not None for c in failed)


@pytest.mark.parametrize("args,words", [
    (["--report", "/nonexistent/dir/r.html"],
     "--report /nonexistent/dir/r.html: the directory /nonexistent/dir does not exist"),
    (["--junit", "."], "--junit .: the name must end in .xml"),
    (["--report", "r.txt"], "--report r.txt: the name must end in .md or .html"),
])
def test_bad_output_paths_stop_before_anything_is_sent(sim_process, tmp_path, args, words):
    """An output file that cannot be written is refused before the port is opened: exit 2, our words."""
    url, proc = sim_process
    r = conformance(["--port", url, *args], tmp_path)
    assert r.returncode == 2
    assert words in r.stderr and "nothing was sent" in r.stderr
    assert "testing" not in r.stdout
    quiet(r)


def test_k_matching_nothing_says_so(tmp_path):
    """-k that selects no check: our words, exit 2 (not pytest's silent exit 5)."""
    r = conformance(["-k", "no_such_check"], tmp_path)
    assert r.returncode == 2, r.stdout
    assert "NOT TESTED: -k 'no_such_check' matches no check" in r.stdout.splitlines()[-1]
    quiet(r)


def test_device_that_vanishes_ends_the_run_with_exit_3(sim_process, tmp_path):
    """The simulator process is killed mid-run (an unplugged adapter): the run stops at the first port
    error with the could-not-go-on verdict, exit 3, and says the device could not be restored."""
    url, proc = sim_process
    run = subprocess.Popen([sys.executable, "-m", "xac1_proto", "conformance", "--port", url, *MOTION,
                            "--scratch-points", "1,2,3,4"], cwd=tmp_path, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True)
    assert run.stdout is not None
    lines = []
    for line in run.stdout:
        lines.append(line)
        if "] echo (check" in line:
            proc.kill()
            break
    out = "".join(lines) + run.stdout.read()
    rc = run.wait(timeout=RUN_TIMEOUT)
    assert rc == 3, out[-3000:]
    last = out.strip().splitlines()[-1]
    assert "THE DEVICE STOPPED ANSWERING" in last or "COULD NOT GO ON" in last, last
    assert "safety NOT RESTORED" in out
    for noise in NOISE:
        assert noise not in out, noise
