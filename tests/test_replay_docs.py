"""docs/replay.md's examples work when pasted: every ``xac1 replay`` command it shows against the
built-in simulator (or with ``--dry-run``) runs and ends with the status the page gives, and its Python
snippet opens the replaying simulator with pyserial and gets the captured faulty echo."""

from __future__ import annotations

import contextlib
import io
import re
import shlex

import pytest
from conftest import ROOT

from xac1_proto.cli import main

PAGE = (ROOT / "docs" / "replay.md").read_text(encoding="utf-8")


def blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", PAGE, re.DOTALL)


RUNNABLE = [line for block in blocks("sh") for line in block.splitlines()
            if line.startswith("xac1 replay ") and ("xac1sim://" in line or "--dry-run" in line)]


def test_the_page_has_runnable_examples():
    """The page shows the replay against the simulator, with JSON lines and a report, and a dry run."""
    assert len(RUNNABLE) >= 3
    assert any("--report" in line for line in RUNNABLE) and any("--dry-run" in line for line in RUNNABLE)


# at the captured pace the gallery session takes seconds (its silent 0RV waits 1.4 s): slow
@pytest.mark.parametrize("command", [
    pytest.param(c, marks=pytest.mark.slow) if "--pace fast" not in c and "--dry-run" not in c else c
    for c in RUNNABLE])
def test_replay_example_runs_as_documented(command, tmp_path, monkeypatch):
    """Pasted in the repository (here: a folder whose ``captures`` is the repository's), the command
    ends with the documented status: 1 for the gallery's faulty device against the clean simulator, 0
    for a dry run; a report it asks for is written."""
    (tmp_path / "captures").symlink_to(ROOT / "captures")
    monkeypatch.chdir(tmp_path)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(shlex.split(command)[1:])
    assert status == (0 if "--dry-run" in command else 1), err.getvalue()
    if "--report" in command:
        assert (tmp_path / "replay.html").read_text(encoding="utf-8").count('class="different"') == 4


def test_python_snippet_gets_the_captured_faulty_echo(monkeypatch, capsys):
    """The page's pyserial snippet, run from the repository, prints the captured device's echo."""
    (snippet,) = blocks("python")
    monkeypatch.chdir(ROOT)
    exec(compile(snippet, "docs/replay.md", "exec"), {})
    assert capsys.readouterr().out.strip() == repr(b"0WP19302012344\r\n")
