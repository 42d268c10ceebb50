"""``xac1 fuzz`` runs in the acceptance history (issue 38): a clean run and a run against a robustness
fault appear in ``xac1 history list --kind fuzz`` with their verdict and exit status, each finding a
failed check with its kind and violation codes, the settings and files kept; ``--no-history`` records
nothing; an unreachable store spools the run with one warning and leaves the exit status alone; the
record built from any run summary names every finding once."""

from __future__ import annotations

import argparse
import datetime as dt
import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from xac1_proto.cli import main
from xac1_proto.cli.fuzz_history import FINDINGS, INCOMPLETE, INTERRUPTED, NO_FINDING, run_record
from xac1_proto.cli.fuzz_run import Limits
from xac1_proto.dut.settings import Settings
from xac1_proto.fuzz.judge import KINDS, Finding
from xac1_proto.fuzz.results import Reported, RunSummary
from xac1_proto.history import spool
from xac1_proto.history.model import RunRecord
from xac1_proto.history.store import Store
from xac1_proto.history.where import store_url

CLEAN = "xac1sim://?time_scale=0"
HANGS = "xac1sim://?time_scale=0&deviation=hang-on-long-line"
# few seeded cases, a short answer window, no shrinking: seed 3 hangs the faulty simulator at case 2
FAST = ("--seed", "3", "--timeout", "0.1", "--shrink-budget", "0", "--max-findings", "1", "-f", "jsonl")


def _history_list(capsys: pytest.CaptureFixture[str]) -> list[dict]:
    capsys.readouterr()
    assert main(["history", "list", "--kind", "fuzz", "--format", "json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.slow
def test_a_clean_run_and_a_run_with_a_finding_are_recorded(private_history, tmp_path, capsys):
    """A run against the clean simulator is recorded as NO FINDING, exit 0, no failed rule; one against
    the hang-on-long-line fault as FINDINGS, exit 1, failed rule ``silence`` with the engine's
    ``no-answer``; both with the unit, operator and station given, the firmware from 0RV, the settings
    (seed, cases, motion, safe range) and the JUnit file; ``--no-history`` records nothing."""
    who = ["--unit-id", "SN-9", "--operator", "ann", "--station", "bench-3"]
    assert main(["fuzz", "--port", CLEAN, "--cases", "4", *FAST, "--no-history"]) == 0
    assert not (private_history / "xac1" / "history.sqlite").exists()
    assert main(["fuzz", "--port", CLEAN, "--cases", "4", *FAST, *who]) == 0
    junit = tmp_path / "fuzz.xml"
    assert main(["fuzz", "--port", HANGS, "--cases", "20", *FAST, *who, "--junit", str(junit)]) == 1
    listed = _history_list(capsys)
    assert [(r["kind"], r["verdict"], r["exit_status"], r["failed_rules"]) for r in listed] == [
        ("fuzz", NO_FINDING, 0, []), ("fuzz", FINDINGS, 1, ["silence"])]
    assert [r["port"] for r in listed] == [CLEAN, HANGS]
    assert {(r["unit"], r["operator"], r["station"], r["firmware"]) for r in listed} == {
        ("SN-9", "ann", "bench-3", "100")}
    with Store.open(store_url(None)) as store:
        clean, found = (s.run for s in store.runs())
    assert clean.checks == ()
    (check,) = found.checks
    assert (check.name, check.outcome, check.topic, check.codes) == ("silence", "FAIL", "silence",
                                                                     ("no-answer",))
    assert "got no answer" in check.message
    assert dict(found.settings) == {"seed": "3", "cases": "20", "motion": "not allowed", "safe range": "-",
                                    "answer window": "0.1 s"}
    assert found.files == (("junit", str(junit.resolve())),)
    assert found.interrupted is None and "1 finding(s) (silence 1)" in found.verdict_line


@pytest.mark.slow
def test_an_unreachable_store_spools_the_run_and_keeps_the_exit_status(private_history, tmp_path, capsys):
    """A store that cannot be opened (its folder cannot be made) never changes the exit status of a run
    with a finding (1): the run is kept in the spool, said in one warning line on stderr."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    url = f"sqlite:///{blocker / 'sub' / 'h.sqlite'}"
    assert main(["fuzz", "--port", HANGS, "--cases", "20", *FAST, "--history", url]) == 1
    warnings = [line for line in capsys.readouterr().err.splitlines() if "history:" in line]
    assert len(warnings) == 1 and "cannot make the folder" in warnings[0] and "spool" in warnings[0]
    (kept,) = spool.waiting()
    run = RunRecord.from_json(json.loads(kept.read_text())["run"])
    assert (run.kind, run.verdict, run.exit_status, run.failed_rules) == ("fuzz", FINDINGS, 1, ["silence"])


T0 = dt.datetime(2026, 11, 29, 2, 0, tzinfo=dt.timezone.utc)
ARGS = argparse.Namespace(report=None, junit=None, safe_range=None)


def _summary(kinds: list[str], interrupted: str | None = None, stopped: str | None = None) -> RunSummary:
    found = [Reported(case=i, found=(b"x\n",), finding=Finding(k, (b"x\n",), f"seen {i}", (f"code-{k}",)),
                      shrunk=True) for i, k in enumerate(kinds)]
    return RunSummary(port=CLEAN, seed=1, cases=len(kinds) + 3, findings=tuple(found), seconds=1.0,
                      version="100", motion=False, interrupted=interrupted, stopped=stopped, restore=(),
                      restored=True, exit=1 if kinds else 0)


def _record(summary: RunSummary) -> RunRecord:
    settings = Settings.make(CLEAN, False, fresh=False, safe_range=None, cli=True)
    return run_record(summary, ARGS, settings, Limits(None, 30.0), T0, T0, {})


@given(st.lists(st.sampled_from(KINDS), max_size=8), st.sampled_from([None, "SIGINT"]))
def test_every_finding_is_one_failed_check_named_after_its_kind(kinds, interrupted):
    """Whatever a run found, its record has one failed check a finding, in order, each name unique and
    starting with the finding's kind (the first of a kind is the kind itself, so ``--rule KIND`` finds
    the run), carrying its codes; the verdict is FINDINGS when anything was found, else INTERRUPTED
    after a signal, else NO FINDING."""
    run = _record(_summary(kinds, interrupted))
    names = [c.name for c in run.checks]
    assert len(set(names)) == len(names) == len(kinds)
    assert [(n.split()[0], c.codes, c.outcome) for n, c in zip(names, run.checks, strict=True)] == [
        (k, (f"code-{k}",), "FAIL") for k in kinds]
    assert set(run.failed_rules) >= set(kinds)
    assert run.verdict == (FINDINGS if kinds else INTERRUPTED if interrupted else NO_FINDING)
    assert run.interrupted == interrupted and run.settings["cases"] == "for 30 s"


def test_a_run_that_ended_early_without_a_finding_is_incomplete():
    """A run that stopped early for another reason than a signal, having found nothing, is not recorded
    as having found nothing: its verdict is INCOMPLETE and the reason is in its verdict line."""
    run = _record(_summary([], stopped="the run stopped: OSError: gone"))
    assert run.verdict == INCOMPLETE and "ended early: the run stopped: OSError: gone" in run.verdict_line
