"""``xac1 fuzz`` end to end: the clean simulator stands up, each robustness fault is found, shrunk,
saved and replayed; options, endings and output files."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, wait_until, xac1, xac1_sim

from xac1_proto.cli import main
from xac1_proto.history.store import Store

# The in-process simulator answers at once; a tenth of a second leaves room for a loaded machine.
FAST = ("--timeout", "0.1", "--seed", "3")


def _jsonl(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


@pytest.mark.parametrize(("args", "says"), [
    (["--safe-range", "0:0x100"], "--safe-range goes with --allow-motion"),
    (["--port", "/dev/ttyUSB99", "--allow-motion"], "--allow-motion needs --safe-range"),
    (["--safe-range", "9:1", "--allow-motion"], "LO 0x000009 is above HI"),
    (["--report", "/"], "--report"),
])
def test_bad_options_exit_2_and_send_nothing(capsys, args, says):
    """A bad option or combination is refused with exit 2, saying what was wrong, before any port is
    opened."""
    assert main(["fuzz", *args]) == 2
    assert says in capsys.readouterr().err


@pytest.mark.parametrize("value", ["0", "-3", "x"])
def test_bad_counts_are_usage_errors(capsys, value):
    """--cases must be a positive count (argparse exits 2 naming it)."""
    with pytest.raises(SystemExit) as exc:
        main(["fuzz", "--cases", value])
    assert exc.value.code == 2 and "--cases" in capsys.readouterr().err


def test_unreachable_unit_exits_3(capsys):
    """A port that does not open is exit 3, nothing sent."""
    assert main(["fuzz", "--port", "socket://127.0.0.1:9", "--cases", "1"]) == 3
    assert "cannot open" in capsys.readouterr().err


def test_a_silent_unit_exits_3(capsys):
    """A unit that never answers at the start (a simulator that drops every byte it sends) is exit 3."""
    port = "xac1sim://?time_scale=0&drop=1"
    assert main(["fuzz", "--port", port, "--cases", "1", "--timeout", "0.05"]) == 3
    assert "cannot read the unit's points" in capsys.readouterr().err


@pytest.mark.slow
def test_clean_simulator_finds_nothing(tmp_path):
    """Against the clean simulator a short seeded run finds nothing and exits 0: one JSON line a case, a
    summary line with the seed, and the report and JUnit written."""
    report, junit = tmp_path / "fuzz.html", tmp_path / "fuzz.xml"
    r = xac1("fuzz", "--cases", "60", *FAST, "--format", "jsonl", "--report", str(report),
             "--junit", str(junit))
    assert r.returncode == 0, r.stderr
    objs = _jsonl(r.stdout)
    assert [o["type"] for o in objs] == ["case"] * 60 + ["summary"]
    summary = objs[-1]
    assert (summary["cases"], summary["findings"], summary["seed"], summary["exit"]) == (60, 0, 3, 0)
    assert summary["restored"] is True
    assert len(summary["generators"]) > 5
    assert all(o["finding"] is None for o in objs[:-1])
    assert "stood up to every case" in report.read_text()
    assert 'failures="0"' in junit.read_text()


# deviation -> (kind of finding, longest shrunk write in bytes)
FAULTS = {"hang-on-long-line": ("silence", 41), "nul-corrupts-point": ("state", 8),
          "late-after-errors": ("silence", 8)}


def _violations(capture: Path, port: str) -> tuple[int, dict]:
    """Replay ``capture`` against ``port``: the exit status and the summary. The new conversation is judged
    with an answer window shorter than the run's (FAST), so an answer the run found late is late here."""
    r = xac1("replay", str(capture), "--port", port, "--format", "jsonl", "--timeout", "0.05")
    return r.returncode, _jsonl(r.stdout)[-1]


@pytest.mark.slow
@pytest.mark.parametrize("deviation", sorted(FAULTS))
def test_each_robustness_fault_is_found_shrunk_and_replayed(tmp_path, deviation):
    """Against {deviation} the run finds the fault, shrinks it to a line or two, saves a capture and
    exits 1; replaying the capture against the faulty simulator shows the finding's violation code
    again, and against the clean simulator it does not."""
    port = f"xac1sim://?time_scale=0&deviation={deviation}"
    report = tmp_path / "fuzz.md"
    r = xac1("fuzz", "--port", port, "--cases", "60", "--max-findings", "1", *FAST, "--format", "jsonl",
             "--save", str(tmp_path), "--report", str(report))
    assert r.returncode == 1, r.stdout[-2000:] + r.stderr
    findings = [o for o in _jsonl(r.stdout) if o["type"] == "finding"]
    assert len(findings) == 1
    f = findings[0]
    kind, longest = FAULTS[deviation]
    assert f["kind"] == kind and f["shrunk"], f
    sent = [x.encode().decode("unicode_escape") for x in f["input"]]
    assert len(sent) <= 2 and max(len(x) for x in sent) <= longest, sent
    assert f["codes"], f
    capture = Path(f["capture"])
    assert capture.parent == tmp_path and capture.exists()
    assert f"### 1. {kind}" in report.read_text()
    faulty_status, faulty = _violations(capture, port)
    clean_status, clean = _violations(capture, "xac1sim://?time_scale=0")
    first = f["codes"][0]  # the fault's own code (no-answer, readback-mismatch); later ones follow from it
    assert first in faulty["violations"], (f["codes"], faulty)
    assert first not in clean["violations"], (f["codes"], clean)
    if deviation != "late-after-errors":  # a late answer is the same answer: only its timing differs
        assert (faulty_status, clean_status) == (0, 1)


@pytest.mark.slow
def test_sigint_ends_the_run_in_order(tmp_path):
    """SIGINT during the run ends it in order: the unit is restored, the summary says so and names the
    signal, and the exit status is that of the findings (0: none); the history records the run as
    INTERRUPTED by SIGINT with that exit status."""
    store = tmp_path / "history.sqlite"
    proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", "fuzz", "--seconds", "60", *FAST,
                             "--format", "jsonl", "--history", str(store)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    try:
        wait_until(lambda: proc.stdout.readline().startswith('{"type": "case"'), 20, "a first case")
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    summary = _jsonl(out)[-1]
    assert summary["type"] == "summary" and summary["interrupted"] == "SIGINT" and summary["restored"]
    assert "restore: 15 of 15 points unchanged" in err or "restored to" in err
    with Store.open(str(store)) as history:
        (recorded,) = (s.run for s in history.runs())
    assert (recorded.kind, recorded.verdict, recorded.exit_status, recorded.interrupted) == (
        "fuzz", "INTERRUPTED", 0, "SIGINT")


@pytest.mark.slow
def test_a_real_unit_that_falls_silent_is_reported_as_found():
    """On a unit that is not the built-in simulator (a simulator over TCP) a silence cannot be shrunk
    without a power cycle and there is no terminal to ask for one: it is reported as found, the run ends
    there, exit 1, and the restore says it could not be verified."""
    with xac1_sim("--tcp", "0", "--time-scale", "0", "--deviation", "hang-on-long-line") as (_, url):
        r = xac1("fuzz", "--port", url, "--cases", "80", "--timeout", "0.1", "--seed", "3",
                 "--format", "jsonl")
    assert r.returncode == 1, r.stderr
    objs = _jsonl(r.stdout)
    finding = next(o for o in objs if o["type"] == "finding")
    assert finding["kind"] == "silence" and not finding["shrunk"]
    assert "no terminal to ask" in finding["not_shrunk_because"]
    summary = objs[-1]
    assert summary["cases"] < 80 and "the run ends here" in summary["stopped"]
    assert summary["restored"] is False
    assert "could not be done or verified" in r.stderr


@pytest.mark.slow
def test_a_silence_is_shrunk_with_the_operator_power_cycling_the_unit(tmp_path):
    """On a unit that is not the built-in simulator, with a terminal to ask on, a silence is shrunk by
    asking the operator to switch the unit off and on before each re-run. The operator here is the test:
    it power-cycles the simulator through its control channel (``power``), waits for its word, then
    presses Enter. The finding is shrunk to one line, and every prompt was answered."""
    import pexpect

    out = tmp_path / "fuzz.jsonl"
    with xac1_sim("--tcp", "0", "--time-scale", "0", "--deviation", "hang-on-long-line") as (sim, url):
        assert sim.stdin is not None and sim.stdout is not None
        command = (f"{sys.executable} -m xac1_proto fuzz --port {url} --cases 80 --timeout 0.1 --seed 3 "
                   f"--format jsonl --max-findings 1 --shrink-budget 12 > {out}")
        child = pexpect.spawn("/bin/sh", ["-c", command], encoding="utf-8", timeout=60, cwd=str(ROOT))
        asked = 0
        while child.expect(["switch the unit off and on again", pexpect.EOF]) == 0:
            asked += 1
            sim.stdin.write("power\n")
            sim.stdin.flush()
            while "power-cycled" not in sim.stdout.readline():  # the control channel's word
                pass
            child.sendline("")
        child.close()
    assert child.exitstatus == 1, child.before
    objs = _jsonl(out.read_text())
    finding = next(o for o in objs if o["type"] == "finding")
    assert asked >= 1
    assert finding["kind"] == "silence" and finding["shrunk"], finding
    assert len(finding["input"]) == 1, finding


@pytest.mark.slow
def test_a_real_unit_is_shrunk_without_a_power_cycle_and_never_written_where_it_cannot_be_restored():
    """On a unit that is not the built-in simulator a state finding is shrunk by re-running after an
    alarm reset; no case wrote a point (none held data, so none could be written back), so point 1's
    change is the unit's own."""
    with xac1_sim("--tcp", "0", "--time-scale", "0", "--deviation", "nul-corrupts-point") as (_, url):
        r = xac1("fuzz", "--port", url, "--cases", "40", "--timeout", "0.1", "--seed", "3",
                 "--format", "jsonl", "--max-findings", "1")
    assert r.returncode == 1, r.stderr
    objs = _jsonl(r.stdout)
    finding = next(o for o in objs if o["type"] == "finding")
    assert finding["kind"] == "state" and finding["shrunk"] and finding["input"] == ["\\x00\\n"], finding
    assert "no case wrote anything" in finding["detail"]


@pytest.mark.slow
def test_progress_bar_on_a_terminal(tmp_path):
    """On a terminal, stderr shows the live progress bar with the cases and findings so far."""
    import os
    import pty

    master, slave = pty.openpty()
    try:
        r = subprocess.run([sys.executable, "-m", "xac1_proto", "fuzz", "--cases", "15", *FAST], cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL, timeout=60,
                           env={**os.environ, "COLUMNS": "120", "TERM": "xterm"})
        os.close(slave)
        seen = b""
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:
                break
            if not data:
                break
            seen += data
    finally:
        os.close(master)
    assert r.returncode == 0
    assert b"xac1 fuzz" in seen and b"cases, 0 finding(s)" in seen, seen[-500:]


@pytest.mark.slow
def test_a_wrong_answer_to_the_probe_is_an_answer_finding():
    """When the unit starts answering 0RV otherwise than at the start (here the simulator's letter-o
    deviation switched on mid-run through its control channel), the next probe gives an ``answer``
    finding naming the engine's code for it (``letter-o``), exit 1."""
    with xac1_sim("--tcp", "0", "--time-scale", "0") as (sim, url):
        args = ["fuzz", "--port", url, "--seconds", "30", "--timeout", "0.1", "--seed", "3",
                "--format", "jsonl", "--max-findings", "1", "--shrink-budget", "5"]
        proc = subprocess.Popen([sys.executable, "-m", "xac1_proto", *args], cwd=ROOT, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        assert proc.stdout is not None and sim.stdin is not None
        try:
            first = proc.stdout.readline()
            assert first.startswith('{"type": "case"'), first
            sim.stdin.write("deviation letter-o on\n")
            sim.stdin.flush()
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 1, err
    finding = next(o for o in _jsonl(out) if o["type"] == "finding")
    assert finding["kind"] == "answer" and "'ORV100'" in finding["detail"], finding
    assert "letter-o" in finding["codes"]


@pytest.mark.slow
def test_allow_motion_mixes_in_moves_inside_the_safe_range():
    """With --allow-motion and a safe range some cases are direct moves, each to a position inside the
    range and answered by its echo; the run on the clean simulator still finds nothing."""
    r = xac1("fuzz", "--allow-motion", "--safe-range", "0x100:0x2000", "--cases", "40", *FAST,
             "--format", "jsonl")
    assert r.returncode == 0, r.stderr
    moves = [o for o in _jsonl(r.stdout) if o.get("generator") == "move"]
    assert moves
    for m in moves:
        (line,) = m["input"]
        assert line.startswith("0MV") and 0x100 <= int(line[6:12], 16) <= 0x2000, line
        assert m["answer"] == line, m
