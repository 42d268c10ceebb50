"""The import graph: the sans-IO core loads no serial, socket, thread or clock module and nothing above
it; ``xac1_proto`` is lazy; ``xac1sim://`` is registered where pyserial users expect it; the ``xac1``
dispatcher imports only the subcommand that runs. Each check runs in a fresh interpreter (a subprocess),
because this test process has long since imported everything.
"""

from __future__ import annotations

import ast
import importlib
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

import xac1_proto
from xac1_proto.cli import COMMANDS

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "xac1_proto"

# The sans-IO core (docs/architecture.md "Layers"); the rulebook engine joins it once it exists.
CORE = ["spec", "grammar", "frames", "codec", "framer", "motion", "chunk", "errors", "exchange", "replay"]
if (PACKAGE / "conversation.py").exists():
    CORE.append("conversation")

# Modules the core must not load: I/O, threads, and everything above the core.
FORBIDDEN_ROOTS = {"serial", "socket", "threading", "select", "selectors", "subprocess", "asyncio",
                   "sniffer", "conformance"}
FORBIDDEN_OWN = {"xac1_proto.client", "xac1_proto.urlhandler", "xac1_proto.sim", "xac1_proto.cli"}
CLOCK_MODULES = {"time", "datetime"}


def fresh(code: str) -> dict:
    """Run ``code`` in a new interpreter; it prints one JSON value, returned here."""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def loaded_after(statements: str) -> list[str]:
    """The modules a fresh interpreter has loaded after running ``statements``."""
    return fresh(f"{statements}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))")


def forbidden(modules: list[str]) -> list[str]:
    return [m for m in modules if m.split(".")[0] in FORBIDDEN_ROOTS
            or any(m == f or m.startswith(f + ".") for f in FORBIDDEN_OWN)]


@pytest.mark.slow  # starts a process
@pytest.mark.parametrize("name", CORE)
def test_core_module_loads_no_io_thread_or_shell(name):
    """Importing a core module alone loads no serial, socket, threading, select and no sniffer,
    conformance, client, URL handler, simulator or CLI module."""
    modules = loaded_after(f"import xac1_proto.{name}")
    assert f"xac1_proto.{name}" in modules
    assert forbidden(modules) == []


@pytest.mark.slow  # starts a process
def test_whole_core_together_loads_nothing_forbidden():
    """All the core modules imported in one interpreter: still nothing forbidden."""
    modules = loaded_after("\n".join(f"import xac1_proto.{n}" for n in CORE))
    assert forbidden(modules) == []


@pytest.mark.slow  # starts a process
def test_forbidden_check_catches_a_shell():
    """The check above is not vacuous: importing the client does load pyserial and threads."""
    found = forbidden(loaded_after("import xac1_proto.client"))
    assert {"serial", "threading", "xac1_proto.client", "xac1_proto.urlhandler"} <= set(found)


@pytest.mark.parametrize("name", CORE)
def test_core_source_imports_no_clock(name):
    """A core module takes time as an argument: its source imports neither ``time`` nor ``datetime``
    (both are always loaded by the interpreter, so only the source can tell)."""
    tree = ast.parse((PACKAGE / f"{name}.py").read_text(encoding="utf-8"))
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            imported.add(node.module.split(".")[0])
    assert imported & CLOCK_MODULES == set()


def test_package_never_imports_a_shell_above_it():
    """No module of xac1_proto imports sniffer or conformance (the dispatcher names them as strings)."""
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            offenders += [f"{path.relative_to(ROOT)}:{node.lineno} imports {n}" for n in names
                          if n.split(".")[0] in {"sniffer", "conformance"}]
    assert offenders == []


@pytest.mark.slow  # starts a process
def test_package_import_is_lazy():
    """``import xac1_proto`` loads no submodule and registers no URL handler; a public name loads its
    module on first use."""
    got = fresh("import sys, json, xac1_proto\n"
                "before = sorted(m for m in sys.modules if m.startswith('xac1_proto.') or m == 'serial')\n"
                "framer = xac1_proto.Framer\n"
                "after = sorted(m for m in sys.modules if m.startswith('xac1_proto.') or m == 'serial')\n"
                "print(json.dumps([before, after, framer.__module__]))")
    before, after, module = got
    assert before == []
    assert module == "xac1_proto.framer"
    assert "xac1_proto.framer" in after and "serial" not in after


def test_public_names_resolve():
    """Every name in ``__all__`` is served by the lazy table and resolves to the real object."""
    assert set(xac1_proto.__all__) - {"__version__"} == set(xac1_proto._LAZY)
    for name, module_name in xac1_proto._LAZY.items():
        value = getattr(xac1_proto, name)
        module = importlib.import_module(module_name, "xac1_proto")
        assert value is module or value is getattr(module, name)
    assert "Client" in dir(xac1_proto)
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = xac1_proto.no_such_name


@pytest.mark.slow  # starts a process
def test_client_registers_the_url_handler():
    """Importing ``xac1_proto.client`` makes ``serial.serial_for_url('xac1sim://')`` work."""
    got = fresh("import json, serial\n"
                "before = 'xac1_proto.urlhandler' in serial.protocol_handler_packages\n"
                "import xac1_proto.client\n"
                "with serial.serial_for_url('xac1sim://?time_scale=0', timeout=2) as p:\n"
                "    p.write(b'0RV\\r\\n'); answer = p.read_until(b'\\n')\n"
                "print(json.dumps([before, answer.decode()]))")
    assert got == [False, "0RV100\r\n"]


SNIPPET_PAGE = ROOT / "docs" / "python-api.md"


def guide_snippet() -> str:
    """The Python API guide's "open xac1sim:// from a pyserial script" snippet (the block after its
    marker)."""
    text = SNIPPET_PAGE.read_text(encoding="utf-8")
    m = re.search(r"<!-- snippet: xac1sim-url -->\n```python\n(.*?)```", text, re.DOTALL)
    assert m, "docs/python-api.md lost its xac1sim:// snippet (marker <!-- snippet: xac1sim-url -->)"
    return m.group(1)


@pytest.mark.slow  # starts a process
def test_guide_snippet_opens_xac1sim_with_pyserial_alone():
    """The guide's snippet, run as a plain pyserial script, talks to the simulator."""
    snippet = guide_snippet()
    assert "import xac1_proto" not in snippet.replace("xac1_proto.urlhandler", "")
    got = fresh(snippet + "\nimport json\nprint(json.dumps(answer.decode()))")
    assert got == "0RV100\r\n"


@pytest.mark.slow  # starts a process
def test_parse_imports_only_its_own_subcommand():
    """``xac1 parse`` imports its module and none of the other seven (nor serial, sniffer, conformance)."""
    modules = loaded_after("import contextlib, io\nfrom xac1_proto.cli import main\n"
                           "with contextlib.redirect_stdout(io.StringIO()):\n"
                           "    assert main(['parse', '--role', 'command', '0RV\\\\r\\\\n']) == 0")
    assert COMMANDS["parse"].module in modules
    others = [c.module for n, c in COMMANDS.items() if n != "parse"]
    assert [m for m in others if m in modules] == []
    assert forbidden(modules) == ["xac1_proto.cli", "xac1_proto.cli.parse_cmd"]


@pytest.mark.slow  # starts a process
def test_help_imports_no_subcommand():
    """``xac1 --help`` is built from the table alone."""
    modules = loaded_after("import contextlib, io\nfrom xac1_proto.cli import main\n"
                           "out = io.StringIO()\n"
                           "with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):\n"
                           "    main(['--help'])\n"
                           "assert 'decode' in out.getvalue()")
    assert [c.module for c in COMMANDS.values() if c.module in modules] == []


@pytest.mark.parametrize("name", list(COMMANDS))
def test_help_table_matches_each_module(name):
    """The dispatcher's help line for a subcommand is its module's ``HELP``, word for word."""
    module = importlib.import_module(COMMANDS[name].module)
    assert COMMANDS[name].help == module.HELP


# ---- no import cycle ----

PACKAGES = ("xac1_proto", "sniffer", "conformance")


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the project's modules it imports, at module level or inside a function."""
    files = {}
    for pkg in PACKAGES:
        for path in (root / pkg).rglob("*.py"):
            parts = path.relative_to(root).with_suffix("").parts
            files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph: dict[str, set[str]] = {}
    for module, path in files.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    base = ".".join(up + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base for a in node.names]
            else:
                continue
            for target in targets:
                while target and target not in files:
                    target = target.rpartition(".")[0]
                if target and target != module:
                    deps.add(target)
        graph[module] = deps
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle():
    """No two modules of the project import each other, directly or round a loop, even inside functions
    (a cycle such as the conformance plugin and report importing each other makes either hard to move)."""
    graph = import_graph()
    assert {"xac1_proto.conversation", "sniffer.analyzer", "conformance.plugin"} <= set(graph)
    assert "xac1_proto.conversation" in graph["sniffer.analyzer"]
    assert cycles(graph) == []


def test_cycle_check_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
