"""How a conformance run starts (issue 24 items 12 and 13): a port that does not open is known before the
first check (no check is shown as under way), and the progress says once how its count of checks
relates to the verdict's (checks of stated rules plus checks that record information); the end's
information block counts the lines it prints (issue 40 item 9)."""

from __future__ import annotations

import io
import itertools
import re
from pathlib import Path

import pytest
from conftest import xac1
from rich.console import Console

from conformance.progress import Progress


def test_progress_says_how_its_count_relates_to_the_verdicts() -> None:
    """``Progress.begin(107, 9)`` says once: 107 checks to run, 98 of stated rules (the verdict's count)
    and 9 that record information; the per-topic lines then count "of 107"."""
    out = io.StringIO()
    progress = Progress(Console(file=out, width=200, force_terminal=False))
    progress.begin(107, 9)
    progress.check("framing", "answer_length")
    assert out.getvalue().splitlines() == [
        "xac1 conformance: 107 checks to run: 98 of stated rules (the verdict counts these) and 9 "
        "that record information",
        "xac1 conformance: [  0.0 s] framing (check 1 of 107)"]


@pytest.mark.slow
def test_a_port_that_does_not_open_is_known_before_the_first_check(tmp_path: Path) -> None:
    """``xac1 conformance --port <a path that does not exist>``: NOT TESTED, exit 3, the reason named,
    and no check shown as started (was: "power_on (check 1 of 107)", "alarms (check 4 of 107)" first)."""
    port = tmp_path / "does-not-exist"
    done = xac1("conformance", "--port", str(port), "--junit", str(tmp_path / "j.xml"), timeout=120)
    assert done.returncode == 3, done.stdout[-2000:]
    assert "(check " not in done.stdout, done.stdout
    assert f"run stopped: cannot open {port}" in done.stdout
    assert done.stdout.splitlines()[-1].startswith("xac1 conformance: NOT TESTED: ")
    assert (tmp_path / "j.xml").stat().st_size > 0  # the JUnit file still says so


@pytest.mark.slow
def test_the_counts_shown_agree_with_the_verdict(tmp_path: Path) -> None:
    """A run with checks of stated rules and checks that record information: the first line gives both
    counts, the progress counts their sum, and the verdict counts the checks of stated rules. The end's
    header names the firmware version as such, and its information block says how many records it prints
    (was "9 information records" at the start and 19 lines at the end, under ``device 100 on ...``)."""
    done = xac1("conformance", "-k", "answer_length or information", timeout=120)
    assert done.returncode == 4, done.stdout[-2000:]  # -k: incomplete
    m = re.search(r"xac1 conformance: (\d+) checks to run: (\d+) of stated rules \(the verdict counts "
                  r"these\) and (\d+) that record information", done.stdout)
    assert m, done.stdout[:2000]
    total, rules, info = map(int, m.groups())
    assert total == rules + info and rules > 0 and info > 0
    assert f"(check 1 of {total})" in done.stdout
    verdict = done.stdout.splitlines()[-1]
    ran = re.search(r"\((\d+) passed, (\d+) failed, ", verdict)
    assert ran and int(ran[1]) + int(ran[2]) == rules, verdict
    assert re.search(r"^firmware \d{3} on xac1sim://", done.stdout, re.M), done.stdout[-3000:]
    lines = done.stdout.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("information: "))
    said = re.match(r"information: (\d+) records? from (\d+) checks? ", lines[head])
    assert said, lines[head]
    block = list(itertools.takewhile(lambda line: line.startswith("  "), lines[head + 1:]))
    assert int(said[1]) == len(block) > 0 and int(said[2]) == info, (lines[head], block)
