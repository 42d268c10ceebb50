"""The shared test machinery does what tests/conftest.py says: a test needing a Debian tool is skipped
with the package named when the tool is missing, and fails instead under CI; the hypothesis profile
follows ``HYPOTHESIS_PROFILE`` / ``CI``; ``wait_until`` fails naming what never happened.

Each tool case is a small pytest session (pytester) with this very conftest.py and PATH holding only
a scratch directory, with or without a stand-in executable of the tool's name."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import hypothesis_profile, wait_until
from hypothesis import settings

CONFTEST = Path(__file__).with_name("conftest.py")
# the session's conftest.py runs ours where it is (its paths are relative to this tree)
USE_OUR_CONFTEST = (f"import runpy\nours = runpy.run_path({str(CONFTEST)!r})\n"
                    "globals().update((k, v) for k, v in ours.items() if not k.startswith('__'))\n")

USES_TOOLS = """
import pytest

@pytest.mark.requires_tool("socat")
def test_socat():
    pass

@pytest.mark.requires_tool("tshark", "editcap")
def test_tshark_and_editcap():
    pass

def test_no_tool():
    pass
"""


@pytest.fixture
def session(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch, tmp_path: Path):
    """Run USES_TOOLS with our conftest and PATH = a scratch bin directory holding ``present`` tools."""
    pytester.makeconftest(USE_OUR_CONFTEST)
    pytester.makepyfile(test_tools=USES_TOOLS)
    outer = hypothesis_profile()  # the inner conftest loads a profile into this process too
    monkeypatch.delenv("HYPOTHESIS_PROFILE", raising=False)

    def run(present: tuple[str, ...] = (), ci: str | None = None) -> pytest.RunResult:
        bin_dir = tmp_path / f"bin-{len(present)}-{ci}"
        bin_dir.mkdir()
        for tool in present:
            exe = bin_dir / tool
            exe.write_text("#!/bin/sh\nexit 0\n")
            exe.chmod(0o755)
        monkeypatch.setenv("PATH", str(bin_dir))
        if ci is None:
            monkeypatch.delenv("CI", raising=False)
        else:
            monkeypatch.setenv("CI", ci)
        return pytester.runpytest_inprocess("-rA", "-p", "no:cacheprovider")

    yield run
    settings.load_profile(outer)


def test_missing_tool_is_skipped_naming_the_package(session):
    """No tool on PATH, CI unset: the tool tests are skipped, each reason naming the tool and the Debian
    package (editcap comes with wireshark-common); the test needing nothing passes."""
    r = session()
    r.assert_outcomes(passed=1, skipped=2)
    out = r.stdout.str()
    assert "socat not found on PATH (Debian package socat: sudo apt-get install socat)" in out
    assert ("tshark, editcap not found on PATH (Debian package tshark, wireshark-common: "
            "sudo apt-get install tshark wireshark-common)") in out


@pytest.mark.parametrize("ci", ["true", "1"])
def test_missing_tool_fails_under_ci(session, ci):
    """No tool on PATH, CI set: the tool tests fail (never skip), saying which package is missing."""
    r = session(ci=ci)
    r.assert_outcomes(passed=1, failed=2)
    out = r.stdout.str()
    assert "socat not found on PATH (Debian package socat" in out
    assert "CI is set, so this test fails instead of being skipped" in out


@pytest.mark.parametrize("ci", ["", "false"])
def test_ci_empty_or_false_is_not_ci(session, ci):
    """``CI=`` and ``CI=false`` are not CI: a missing tool skips."""
    session(ci=ci).assert_outcomes(passed=1, skipped=2)


def test_partly_present_names_only_what_is_missing(session):
    """tshark present, editcap and socat missing, CI set: both tool tests fail, naming only editcap's
    package for the second."""
    r = session(present=("tshark",), ci="true")
    r.assert_outcomes(passed=1, failed=2)
    out = r.stdout.str()
    assert "editcap not found on PATH (Debian package wireshark-common" in out
    assert "tshark, editcap not found" not in out


def test_present_tools_run_under_ci(session):
    """Every tool on PATH, CI set: all tests run and pass."""
    session(present=("socat", "tshark", "editcap"), ci="true").assert_outcomes(passed=3)


def test_unknown_tool_is_an_error_naming_the_table(pytester: pytest.Pytester, session):
    """A tool with no known package fails the test, naming where to add it."""
    pytester.makepyfile(test_tools="import pytest\n@pytest.mark.requires_tool('frobnicate')\n"
                                   "def test_x():\n    pass\n")
    r = session()
    r.assert_outcomes(failed=1)
    r.stdout.fnmatch_lines(["*no Debian package known for frobnicate*TOOL_PACKAGES in tests/conftest.py*"])


def test_hypothesis_profiles(monkeypatch):
    """``ci``: derandomized, no deadline, no database, failing blobs printed; ``dev``: random, with
    hypothesis's example database; the choice: HYPOTHESIS_PROFILE, else ``ci`` under CI, else ``dev``."""
    ci, dev = settings.get_profile("ci"), settings.get_profile("dev")
    assert (ci.derandomize, ci.deadline, ci.database, ci.print_blob) == (True, None, None, True)
    assert (dev.derandomize, dev.deadline, dev.print_blob) == (False, None, False)
    assert dev.database is not None
    for env, want in (({"CI": "true"}, "ci"), ({}, "dev"), ({"HYPOTHESIS_PROFILE": "ci"}, "ci"),
                      ({"CI": "true", "HYPOTHESIS_PROFILE": "dev"}, "dev")):
        for name in ("CI", "HYPOTHESIS_PROFILE"):
            monkeypatch.delenv(name, raising=False)
        for name, value in env.items():
            monkeypatch.setenv(name, value)
        assert hypothesis_profile() == want, env


SHOW_SETTINGS = """
from hypothesis import settings

def test_show():
    s = settings()
    print("SETTINGS", s.derandomize, s.deadline, s.database is None)
"""


@pytest.mark.slow
@pytest.mark.parametrize("env,want", [
    ({"CI": "true", "HYPOTHESIS_PROFILE": "dev"}, "SETTINGS False None False"),
    ({"CI": "true"}, "SETTINGS True None True"),
])
def test_a_fresh_session_runs_with_the_chosen_profile(pytester, monkeypatch, env, want):
    """In a fresh pytest process the conftest's choice is what tests get, even where hypothesis itself
    would load its built-in ``ci`` profile (CI set, HYPOTHESIS_PROFILE=dev)."""
    monkeypatch.delenv("HYPOTHESIS_PROFILE", raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    pytester.makeconftest(USE_OUR_CONFTEST)
    pytester.makepyfile(SHOW_SETTINGS)
    r = pytester.runpytest_subprocess("-s", "-p", "no:cacheprovider")
    r.assert_outcomes(passed=1)
    r.stdout.fnmatch_lines([f"*{want}*"])


def test_wait_until_returns_the_value_or_names_what_never_happened():
    """wait_until returns the first truthy value; on timeout it fails naming what it waited for."""
    calls = iter([0, [], "ready"])
    assert wait_until(lambda: next(calls), 1.0, "the third poll", interval=0) == "ready"
    with pytest.raises(AssertionError, match=r"waited 0.05 s for the answer to arrive; it never happened"):
        wait_until(lambda: b"", 0.05, "the answer to arrive")
