"""File names made from port URLs (issue 24 item 7): ``--report-dir`` names are bounded (a long URL cut,
ending with a hash of it), distinct, and checked before any device run starts."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import budget, xac1
from hypothesis import given, settings
from hypothesis import strategies as st

from conformance.fleet import MAX_STEM, FleetError, Target, check_names, file_names, slug

LONG = "xac1sim://?time_scale=0&seed=" + "0" * 280  # + a last digit: 310 characters, a valid seed


@settings(max_examples=budget(80))
@given(st.lists(st.text(min_size=1, max_size=400), min_size=1, max_size=6, unique=True))
def test_port_file_names_are_short_safe_and_distinct(urls: list[str]) -> None:
    """Whatever the URLs (300 characters, odd characters), each device's file stem is at most
    ``MAX_STEM`` characters of letters, digits, ``.``, ``_`` and ``-``, and no two devices share one."""
    stems = file_names([Target(u, "--port") for u in urls])
    assert all(re.fullmatch(r"[A-Za-z0-9._-]+", s) and len(s) <= MAX_STEM + 4 for s in stems), stems
    assert len(set(stems)) == len(stems)


def test_long_urls_that_differ_at_their_end_get_two_names() -> None:
    """Two 310-character URLs alike but for their last character: two stems, each cut with a hash; a
    short URL keeps its readable slug."""
    a, b = slug(LONG + "1"), slug(LONG + "2")
    assert a != b and len(a) == len(b) == MAX_STEM and a[:60] == b[:60]
    assert slug("socket://127.0.0.1:4001") == "socket-127.0.0.1-4001"


def test_a_folder_too_deep_for_the_names_is_refused(tmp_path: Path) -> None:
    """A report folder whose path leaves no room for a device's file name: FleetError naming the
    folder, before anything starts."""
    check_names(tmp_path, [slug(LONG + "1")], (".html", ".xml", ".log"))
    with pytest.raises(FleetError, match="--report-dir .*file name would be too long"):
        check_names(tmp_path, ["x" * 300], (".html",))


@pytest.mark.slow
def test_fleet_of_two_300_character_urls_writes_its_reports(tmp_path: Path) -> None:
    """``xac1 conformance --port <310 characters> --port <310 characters> --report-dir DIR``: both
    devices run and their files are written under bounded names (was: ``OSError: File name too long``
    after the runs had started, exit 1)."""
    out = tmp_path / "out"
    done = xac1("conformance", "--port", LONG + "1", "--port", LONG + "2", "-k", "answer_length",
                "--report-dir", str(out), timeout=240)
    assert "Traceback" not in done.stdout + done.stderr, done.stderr[-2000:]
    assert done.returncode == 4, done.stdout[-2000:]  # -k: incomplete, each device checked
    assert done.stdout.splitlines()[-1] == "xac1 conformance: fleet of 2: 2 INCOMPLETE (exit status 4)"
    for url in (LONG + "1", LONG + "2"):
        for suffix in (".html", ".xml", ".log"):
            assert (out / f"{slug(url)}{suffix}").stat().st_size > 0
