"""The documentation: docs/protocol.md's generated tables match spec.py and every citation of it
resolves; the README is short and links its guides; every option of every ``xac1`` command is documented
somewhere in README.md or docs/; every ``python`` snippet of the guides runs.

A citation is ``docs/protocol.md "Section"`` (one or more quoted section names, possibly wrapped over a
comment or docstring line) or ``silent item N`` anywhere in the code, the README, the guides, the suite
and its data tables (the simulator's deviation table, the conformance suite's information rows,
spec.VIOLATION_SPECS).
"""

from __future__ import annotations

import argparse
import importlib
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from xac1_proto import docgen, spec
from xac1_proto.sim.config import DEVIATIONS

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "protocol.md"
README = ROOT / "README.md"
README_MAX_BYTES = 12 * 1024
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


def guides() -> list[Path]:
    """The guides: every page of docs/ but the protocol reference."""
    return sorted(p for p in (ROOT / "docs").glob("*.md") if p != PAGE)


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
    files = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *guides()]
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
        assert f"| `{v.code}` | {v.code} | {v.severity} |" in text  # the code's plain rule (rules.py)


@pytest.mark.slow  # three processes
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


def test_page_has_the_cited_sections_and_twenty_two_silent_items():
    """The sections the code cites exist under those names; the silent items are numbered 1-22."""
    text = PAGE.read_text(encoding="utf-8")
    assert headings(text) == [
        "Line", "Framing", "Fields", "Frames", "Behaviour the vendor text states", "Alarms",
        SILENT_SECTION, "Violation codes",
    ]
    assert silent_items(text) == list(range(1, 23))


def test_the_citation_scanner_finds_bad_citations():
    """The scanner behind the next test does see wrapped names, lists and ranges, and flags misses."""
    page = PAGE.read_text(encoding="utf-8")
    sample = ('x  # docs/protocol.md "Behaviour\n    # the vendor text states", "Nowhere"\n'
              'docs/protocol.md: "Fields" and "Frames"; silent items 2, 21-23\n')
    found = citations(sample)
    assert [w for _, w in found] == [
        "Behaviour the vendor text states", "Nowhere", "Fields", "Frames",
        "silent item 2", "silent item 21", "silent item 22", "silent item 23"]
    assert unresolved(found, page) == [(1, "Nowhere"), (3, "silent item 23")]


def test_every_citation_in_the_project_resolves():
    """Every docs/protocol.md "Section" and silent item N cited in code, tests, README, guides resolves."""
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


# ---- the README and the guides ----

_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def test_readme_is_short_and_opens_with_install_and_the_two_commands():
    """The README is at most 12 KB, and its first 60 lines hold the install, the main job on the
    built-in simulator, and the tests (the inner loop and the full run)."""
    text = README.read_text(encoding="utf-8")
    assert len(text.encode("utf-8")) <= README_MAX_BYTES
    head = "\n".join(text.splitlines()[:60])
    for needed in ("pip install -e", "xac1 conformance ", 'pytest -m "not slow"', "\npytest "):
        assert needed in head, needed


def test_readme_links_a_guide_for_every_task():
    """Each task section of the README links its guide, and every guide in docs/ is linked from the
    README (a guide nobody can find is lost)."""
    text = README.read_text(encoding="utf-8")
    linked = set(_LINK.findall(text))
    tasks = text.split("## Tasks\n", 1)[1].split("\n## ", 1)[0]
    for section in tasks.split("\n### ")[1:]:
        assert _LINK.search(section), f"README task without a link: {section.splitlines()[0]}"
    guide_names = {p.relative_to(ROOT).as_posix() for p in guides()}
    assert guide_names - linked == set()


def test_every_relative_link_in_the_docs_resolves():
    """Every relative link of README.md, CONTRIBUTING.md, CHANGELOG.md and the guides names a file that
    exists."""
    bad = []
    for page in [README, ROOT / "CONTRIBUTING.md", ROOT / "CHANGELOG.md", *guides()]:
        for target in _LINK.findall(page.read_text(encoding="utf-8")):
            if "://" in target or target.startswith("mailto:"):
                continue
            path = (page.parent / target).resolve()
            if not path.exists():
                bad.append(f"{page.relative_to(ROOT)}: {target}")
    assert not bad, "links to nothing:\n" + "\n".join(bad)


def test_exit_status_table_has_a_row_for_every_command():
    """The README's one exit-status table names every ``xac1`` command, and the conformance verdicts it
    gives include NOT TESTED."""
    from xac1_proto.cli import COMMANDS

    text = README.read_text(encoding="utf-8")
    table = text.split("## Exit statuses\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    named = {m for line in rows for m in re.findall(r"`([a-z]+)", line.split("|")[1])}
    assert set(COMMANDS) - named == set()
    assert "NOT TESTED" in table


def test_conformance_guide_gives_each_verdict_its_exit_status():
    """docs/conformance.md's verdict table gives each verdict the exit status the code gives it (the
    fleet's verdicts, the report's constants)."""
    from conformance import report
    from conformance.fleet import CONFORMS, EXIT, INCOMPLETE, NOT_CONFORM, NOT_TESTED

    text = (ROOT / "docs" / "conformance.md").read_text(encoding="utf-8")
    table = text.split("## Verdicts and exit statuses\n", 1)[1].split("\n## ", 1)[0]
    first = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 3 and cells[0].startswith("`"):
            first.setdefault(cells[0].strip("`"), cells[1].split()[0])
    for verdict in (CONFORMS, NOT_CONFORM, INCOMPLETE, NOT_TESTED):
        assert first[verdict] == str(EXIT[verdict]), verdict
    for verdict in ("NO ANSWER FROM THE DEVICE", "THE DEVICE STOPPED ANSWERING", "COULD NOT GO ON"):
        assert first[verdict] == str(report.EXIT_COULD_NOT_GO_ON), verdict


def _options(parser: argparse.ArgumentParser) -> Iterator[tuple[str, str]]:
    """(where, option string) for every option of ``parser`` and of its sub-parsers, ``-h`` aside."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from ((f"{name} {where}".strip(), o) for where, o in _options(sub))
        elif not isinstance(action, argparse._HelpAction):
            yield from (("", o) for o in action.option_strings)


def command_options() -> list[tuple[str, str]]:
    """("xac1 COMMAND [SUB]", option) for every option of every command of ``xac1``."""
    from xac1_proto.cli import COMMANDS

    out = []
    for name, command in COMMANDS.items():
        parser = argparse.ArgumentParser(prog=f"xac1 {name}")
        importlib.import_module(command.module).add_arguments(parser)
        out += [(f"xac1 {name} {where}".strip(), option) for where, option in _options(parser)]
    return out


def undocumented(options: list[tuple[str, str]], text: str) -> list[str]:
    """The options that appear nowhere in ``text`` as a whole word (``--port`` is not ``--ports``)."""
    return [f"{where} {option}" for where, option in options
            if not re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", text)]


def documentation() -> str:
    return "\n".join(p.read_text(encoding="utf-8") for p in [README, *sorted((ROOT / "docs").glob("*.md"))])


def test_the_option_walk_sees_subcommands_and_misses():
    """The walk behind the next test reaches sub-parsers' options (``xac1 wireshark install
    --uninstall``) and reports an option the text lacks, and ``--port`` documented is not ``--ports``."""
    options = command_options()
    assert ("xac1 wireshark install", "--uninstall") in options
    assert ("xac1 decode", "-I") in options and ("xac1 conformance", "--junitxml") in options
    assert undocumented([("xac1 x", "--ports"), ("xac1 x", "-k")], "use --port or -kx") == [
        "xac1 x --ports", "xac1 x -k"]


def test_every_option_of_every_command_is_documented():
    """Every option string of every ``xac1`` command (aliases too) appears in README.md or docs/*.md:
    nothing the README said before is lost, and a new option comes with its documentation."""
    missing = undocumented(command_options(), documentation())
    assert not missing, "options documented nowhere in README.md or docs/:\n" + "\n".join(missing)


def python_snippets() -> list[tuple[str, str]]:
    """(page:line, code) for every ```python block of the README and the guides."""
    out = []
    for page in [README, *guides()]:
        text = page.read_text(encoding="utf-8")
        for m in re.finditer(r"^```python\n(.*?)^```", text, re.DOTALL | re.MULTILINE):
            out.append((f"{page.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}", m.group(1)))
    return out


@pytest.mark.parametrize(("where", "code"), python_snippets(), ids=lambda v: v if ":" in v else "")
def test_python_snippets_run(where, code, monkeypatch, capsys):
    """Every ``python`` snippet of the README and the guides runs as is from the project's root (against
    the built-in simulator, the gallery captures), its own asserts included."""
    monkeypatch.chdir(ROOT)
    exec(compile(code, where, "exec"), {"__name__": "__snippet__"})


def test_the_guides_have_python_snippets():
    """The Python API guide shows the client, the codec, the engine and the readers, each in code."""
    code = "\n".join(c for w, c in python_snippets() if w.startswith("docs/python-api.md"))
    for needed in ("Client(", "parse(", "Framer()", "Conversation()", "Analyzer()", "Capture("):
        assert needed in code, needed


def test_capture_files_named_in_the_examples_exist():
    """Every ``captures/...`` file (or glob) the README's and the guides' examples name is in the
    gallery, so the examples work when pasted from the project's root."""
    named = set()
    for page in [README, *guides()]:
        for block in re.findall(r"^```(?:sh|console)\n(.*?)^```", page.read_text(encoding="utf-8"),
                                re.DOTALL | re.MULTILINE):
            named |= set(re.findall(r"(captures/[\w.*?-]+)", block))
    assert len(named) > 5
    assert [n for n in sorted(named) if not list(ROOT.glob(n))] == []


def test_citations_of_the_readme_name_its_sections():
    """Code, tests and pages that cite ``README "Section"`` name a section the README has (the reference
    moved to docs/: a citation of a section that left the README points at nothing)."""
    heads = set(re.findall(r"^#{2,3} (.+)$", README.read_text(encoding="utf-8"), re.MULTILINE))
    bad = []
    for path in scanned_files():
        text = path.read_text(encoding="utf-8")
        for m in re.finditer(r'README \\?"([^"\\]+)\\?"', text):
            if m.group(1) not in heads:
                line = text.count("\n", 0, m.start()) + 1
                bad.append(f"{path.relative_to(ROOT)}:{line}: {m.group(1)!r}")
    assert not bad, "README sections cited that the README does not have:\n" + "\n".join(bad)


# ---- the module table of docs/architecture.md ----

ARCHITECTURE = Path(__file__).resolve().parent.parent / "docs" / "architecture.md"
NAMED_BY_FOLDER = ("conformance/checks/",  # one module per protocol topic: the folder names them
                   "xac1_proto/history/migrations/versions/")  # one module per schema revision


def named_modules(text: str) -> set[str]:
    """The module paths architecture.md's "Module names" table names: a row's first path gives the folder
    (``sniffer/analyzer.py`` -> ``sniffer/``; ``xac1_proto/sim/``), against which every other ``name.py``
    in the row is read; a path with a slash is read as it is."""
    section = text[text.index("## Module names"):]
    named = set()
    for row in section.splitlines():
        paths = re.findall(r"`([\w./]+)`", row)
        if not row.startswith("| `") or not paths:
            continue
        first = paths[0]
        folder = first if first.endswith("/") else first.rpartition("/")[0] + "/"
        for path in paths:
            if path.endswith((".py", "/")):
                whole = path.startswith(("xac1_proto/", "sniffer/", "conformance/"))
                named.add(path if whole else folder + path)
    return named


def unnamed_modules(root: Path, named: set[str]) -> list[str]:
    """The modules of the three packages the table does not name (``__init__.py`` and the checks aside)."""
    out = []
    for package in ("xac1_proto", "sniffer", "conformance"):
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            if path.name != "__init__.py" and rel not in named and not rel.startswith(NAMED_BY_FOLDER):
                out.append(rel)
    return out


def test_architecture_names_every_module():
    """docs/architecture.md's module table names every module of xac1_proto, sniffer and conformance, so a
    new module cannot go undocumented."""
    named = named_modules(ARCHITECTURE.read_text(encoding="utf-8"))
    assert unnamed_modules(ARCHITECTURE.parent.parent, named) == []


def test_the_module_table_reader_reads_rows_and_misses(tmp_path):
    """The reader above is not vacuous: names in a row are read against its folder, and a module the table
    leaves out is reported."""
    text = "## Module names\n| `sniffer/analyzer.py`, `view.py` | x |\n| `xac1_proto/sim/` | `model.py` |\n"
    assert named_modules(text) == {"sniffer/analyzer.py", "sniffer/view.py", "xac1_proto/sim/",
                                   "xac1_proto/sim/model.py"}
    for rel in ("sniffer/analyzer.py", "sniffer/view.py", "sniffer/new.py", "xac1_proto/sim/model.py"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("")
    assert unnamed_modules(tmp_path, named_modules(text)) == ["sniffer/new.py"]
