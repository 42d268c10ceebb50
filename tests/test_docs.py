"""docs/protocol.md: its generated tables match spec.py, and every citation of it resolves.

A citation is ``docs/protocol.md "Section"`` (one or more quoted section names, possibly wrapped over a
comment or docstring line) or ``silent item N`` anywhere in the code, the README, the suite and its data
tables (the simulator's deviation table, the conformance suite's information rows, spec.VIOLATION_SPECS).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from xac1_proto import docgen, spec
from xac1_proto.sim.config import DEVIATIONS

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "protocol.md"
SCANNED_DIRS = ("xac1_proto", "sniffer", "conformance", "tests", "benchmarks", "captures")
SCANNED_SUFFIXES = {".py", ".md", ".j2", ".ini", ".toml"}
SILENT_SECTION = "Where the vendor text is silent"

# docs/protocol.md followed by quoted section names: "A", "B" and "C"; a name may wrap onto the next
# comment line ("Behaviour\n    # the vendor text states").
_SECTIONS_CITED = re.compile(
    r'docs/protocol\.md[:,]?\s+((?:"[A-Z][A-Za-z #\n-]*"(?:\s*(?:,|and)\s*)?)+)')
_QUOTED = re.compile(r'"([^"]+)"')
_SILENT = re.compile(r"silent items? (\d+(?:\s*(?:,|and|-)\s*\d+)*)")
_INFO_SECTION = re.compile(r'\.info\(\s*(?:f?"[^"]*"|[a-z_]+)\s*,\s*"([^"]+)"')


def headings(text: str) -> list[str]:
    return re.findall(r"^## (.+)$", text, re.MULTILINE)


def silent_items(text: str) -> list[int]:
    """The numbers of the items of the "Where the vendor text is silent" section, in page order."""
    body = text.split(f"## {SILENT_SECTION}\n", 1)[1].split("\n## ", 1)[0]
    return [int(n) for n in re.findall(r"^(\d+)\. ", body, re.MULTILINE)]


def _normalise(name: str) -> str:
    return " ".join(w for w in name.replace("#", " ").split())


def citations(text: str) -> list[tuple[int, str]]:
    """(line, cited thing) for every section name and every silent item cited in ``text``."""
    out: list[tuple[int, str]] = []
    for m in _SECTIONS_CITED.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        out += [(line, _normalise(q)) for q in _QUOTED.findall(m.group(1))]
    for m in _SILENT.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        for part in re.split(r"\s*(?:,|and)\s*", m.group(1)):
            lo, _, hi = part.partition("-")
            out += [(line, f"silent item {n}") for n in range(int(lo), int(hi or lo) + 1)]
    return out


def unresolved(cited: list[tuple[int, str]], page: str) -> list[tuple[int, str]]:
    sections, items = set(headings(page)), set(silent_items(page))
    bad = []
    for line, what in cited:
        m = re.fullmatch(r"silent item (\d+)", what)
        if (int(m.group(1)) not in items) if m else (what not in sections):
            bad.append((line, what))
    return bad


def scanned_files() -> list[Path]:
    files = [ROOT / "README.md"]
    for d in SCANNED_DIRS:
        files += sorted(p for p in (ROOT / d).rglob("*") if p.suffix in SCANNED_SUFFIXES and p.is_file())
    return [p for p in files if p.resolve() != Path(__file__).resolve()]  # this file cites on purpose


def test_generated_tables_are_up_to_date():
    """The frame, alarm and violation tables of docs/protocol.md are what spec.py generates."""
    text = PAGE.read_text(encoding="utf-8")
    assert docgen.update(text) == text, (
        "docs/protocol.md is out of date with xac1_proto/spec.py: run python -m xac1_proto.docgen --write")


def test_generated_tables_cover_the_spec():
    """Every frame kind, alarm code and violation code of spec.py has its row on the page."""
    text = PAGE.read_text(encoding="utf-8")
    for fs in spec.FRAME_SPECS:
        assert f"| `{fs.header}` |" in text
        assert f"| {fs.length} |" in text
    for code in spec.ALARMS:
        assert f"`{spec.ALARM_HEADER}{spec.FIELDS['code'].show(code)}`" in text
    for v in spec.VIOLATION_SPECS:
        assert f"| `{v.code}` | {v.severity} |" in text


def test_check_names_the_command_when_stale(tmp_path):
    """``docgen --check`` on a page whose table lost a row exits 1 and says how to regenerate it;
    ``--write`` puts the row back and ``--check`` is then content."""
    stale = tmp_path / "protocol.md"
    text = PAGE.read_text(encoding="utf-8")
    row = "| `bad-length` |"
    stale.write_text("\n".join(ln for ln in text.split("\n") if not ln.startswith(row)), encoding="utf-8")
    run = [sys.executable, "-m", "xac1_proto.docgen", "--path", str(stale)]
    r = subprocess.run([*run, "--check"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    assert "python -m xac1_proto.docgen --write" in r.stderr
    assert subprocess.run([*run, "--write"], capture_output=True, timeout=60).returncode == 0
    assert stale.read_text(encoding="utf-8") == text
    assert subprocess.run([*run, "--check"], capture_output=True, timeout=60).returncode == 0


def test_missing_marker_is_a_clear_error():
    """A page without one of the marker pairs is refused, naming the missing block."""
    text = PAGE.read_text(encoding="utf-8").replace("<!-- generated: alarms -->", "")
    with pytest.raises(docgen.DocError, match="generated: alarms"):
        docgen.update(text)


def test_page_has_the_cited_sections_and_twenty_silent_items():
    """The sections the code cites exist under those names; the silent items are numbered 1-20."""
    text = PAGE.read_text(encoding="utf-8")
    assert headings(text) == [
        "Line", "Framing", "Fields", "Frames", "Behaviour the vendor text states", "Alarms",
        SILENT_SECTION, "Violation codes",
    ]
    assert silent_items(text) == list(range(1, 21))


def test_the_citation_scanner_finds_bad_citations():
    """The scanner behind the next test does see wrapped names, lists and ranges, and flags misses."""
    page = PAGE.read_text(encoding="utf-8")
    sample = ('x  # docs/protocol.md "Behaviour\n    # the vendor text states", "Nowhere"\n'
              'docs/protocol.md: "Fields" and "Frames"; silent items 2, 19-21\n')
    found = citations(sample)
    assert [w for _, w in found] == [
        "Behaviour the vendor text states", "Nowhere", "Fields", "Frames",
        "silent item 2", "silent item 19", "silent item 20", "silent item 21"]
    assert unresolved(found, page) == [(1, "Nowhere"), (3, "silent item 21")]


def test_every_citation_in_the_project_resolves():
    """Every docs/protocol.md "Section" and silent item N cited in code, tests, README resolves."""
    page = PAGE.read_text(encoding="utf-8")
    bad, count = [], 0
    for path in scanned_files():
        text = path.read_text(encoding="utf-8")
        found = citations(text)
        found += [(text.count("\n", 0, m.start()) + 1, m.group(1)) for m in _INFO_SECTION.finditer(text)
                  if not m.group(1).startswith("silent item")]
        count += len(found)
        bad += [f"{path.relative_to(ROOT)}:{line}: {what!r}"
                for line, what in unresolved([(ln, _strip_detail(w)) for ln, w in found], page)]
    assert count > 50  # the scan really reads the project
    assert not bad, "citations of docs/protocol.md that name no section or item:\n" + "\n".join(bad)


def _strip_detail(cited: str) -> str:
    """``Frames (0RV)`` -> ``Frames``: a section name with a detail in parentheses."""
    return cited.split(" (", 1)[0]


def test_data_tables_cite_real_sections():
    """The sections named by spec.VIOLATION_SPECS and the simulator's deviation table resolve."""
    page = PAGE.read_text(encoding="utf-8")
    cited = [(0, v.section) for v in spec.VIOLATION_SPECS]
    for _rule, sections in DEVIATIONS.values():
        cited += [(0, _strip_detail(part.strip())) for part in sections.split(";")]
    assert unresolved(cited, page) == []
