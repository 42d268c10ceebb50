"""The import graph: the sans-IO core loads no serial, socket, thread or clock module and nothing above
it; ``xac1_proto`` is lazy; ``xac1sim://`` is registered where pyserial users expect it; the ``xac1``
dispatcher imports only the subcommand that runs. Each check runs in a fresh interpreter (a subprocess),
because this test process has long since imported everything.
"""

from __future__ import annotations

import ast
import functools
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
CORE = ["spec", "grammar", "frames", "points", "codec", "framer", "motion", "chunk", "errors", "exchange",
        "replay"]
if (PACKAGE / "conversation.py").exists():
    CORE += ["conversation", "latch", "waiting", "sentences"]

# Modules the core must not load: I/O, threads, and everything above the core.
FORBIDDEN_ROOTS = {"serial", "socket", "threading", "select", "selectors", "subprocess", "asyncio",
                   "sniffer", "conformance"}
FORBIDDEN_OWN = {"xac1_proto.client", "xac1_proto.urlhandler", "xac1_proto.sim", "xac1_proto.cli"}
CLOCK_MODULES = {"time", "datetime"}


@functools.cache
def parsed(path: Path) -> ast.Module:
    """A source file's syntax tree, parsed once a test session (several checks read every module)."""
    return ast.parse(path.read_text(encoding="utf-8"))


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
    tree = parsed(PACKAGE / f"{name}.py")
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
        for node in ast.walk(parsed(path)):
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


def dynamic_import(node: ast.AST) -> str | None:
    """The module a call ``importlib.import_module("literal")``, ``import_module("literal")`` or
    ``__import__("literal")`` loads; None for any other node (or a name not written out)."""
    if not isinstance(node, ast.Call) or not node.args:
        return None
    func = node.func
    called = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
    first = node.args[0]
    if called in {"import_module", "__import__"} and isinstance(first, ast.Constant) \
            and isinstance(first.value, str):
        return first.value
    return None


@functools.cache
def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the project's modules it imports, at module level or inside a function, by an import
    statement or by ``importlib.import_module``/``__import__`` of a literal name (made once a session:
    the checks only read it)."""
    files = {}
    for pkg in PACKAGES:
        for path in (root / pkg).rglob("*.py"):
            parts = path.relative_to(root).with_suffix("").parts
            files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph: dict[str, set[str]] = {}
    for module, path in files.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        deps: set[str] = set()
        for node in ast.walk(parsed(path)):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    base = ".".join(up + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base for a in node.names]
            elif (name := dynamic_import(node)) is not None:
                targets = [name]
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
    """The cycle check is not vacuous: a loop of three modules is found, a module leading into it is not part
    of it."""
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_dynamic_imports_are_arrows_too():
    """``importlib.import_module("x")`` and ``__import__("x")`` with a literal name count as imports."""
    tree = ast.parse("import importlib\nimportlib.import_module('a.b')\n__import__('c')\n"
                     "importlib.import_module(name)\nprint('d')")
    assert [n for node in ast.walk(tree) if (n := dynamic_import(node))] == ["a.b", "c"]


# ---- packages in layers ----

# Each package's layer, lowest first (docs/architecture.md "Layers"). A package here is a subpackage, or a
# shell module that sits apart from the flat modules of xac1_proto (the core and its small helpers). A
# package imports only packages of a lower layer: never one beside it (the same layer) or above it.
LAYERS = {
    "xac1_proto": 0,  # the sans-IO core and the small helpers beside it (chunk, recording, signals...)
    "xac1_proto.pages": 1, "xac1_proto.sim": 1,  # report pages; the simulator (its model and shells)
    "xac1_proto.urlhandler": 2,  # xac1sim://, around the simulator's model
    "xac1_proto.client": 3,  # the host client, which opens URLs and so registers xac1sim://
    "xac1_proto.history": 2,  # the acceptance history (its store, views and trend page)
    "xac1_proto.console": 4, "xac1_proto.dut": 4,  # the console; the device under test (through a client)
    "xac1_proto.fuzz": 5,  # xac1 fuzz's core: its views share the evidence's escapes
    "xac1_proto.cli": 6, "xac1_proto.entry": 7,  # the xac1 commands; the console script
    "xac1_proto.__main__": 8,  # python -m xac1_proto
    "sniffer": 8, "conformance": 8,  # side by side above the core, each its own
}
FACADE = "xac1_proto"  # the package's lazy public face: it names its modules as strings (and imports them
# for type checkers only), so it sits on top of them all and is left out of the arrows


def package_of(module: str) -> str:
    """The innermost package of ``LAYERS`` a module belongs to."""
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        if ".".join(parts[:n]) in LAYERS:
            return ".".join(parts[:n])
    raise AssertionError(f"{module} is in no package of LAYERS: add its package to the table")


def package_arrows(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    """(importer's package, imported package) for every import across packages."""
    return {(package_of(m), package_of(d)) for m, deps in graph.items() if m != FACADE for d in deps
            if package_of(m) != package_of(d)}


def layer_breaks(arrows: set[tuple[str, str]]) -> list[str]:
    """The arrows that go sideways or up (to a package of the same or a higher layer)."""
    return sorted(f"{a} -> {b}" for a, b in arrows if LAYERS[b] >= LAYERS[a])


def test_packages_import_only_below_them():
    """No package imports one beside or above it: sniffer and conformance only import xac1_proto, never
    each other; inside xac1_proto a shell package (sim, dut, cli...) imports only packages below it
    (import statements and literal dynamic imports alike), so no package loop exists."""
    arrows = package_arrows(import_graph())
    assert {("sniffer", "xac1_proto.dut"), ("conformance", "xac1_proto.dut"),
            ("conformance", "xac1_proto.pages")} <= arrows
    assert layer_breaks(arrows) == []


def test_layer_check_catches_sideways_and_upward_arrows():
    """The check above is not vacuous: sniffer -> conformance (beside) and xac1_proto -> sniffer (above)
    are both caught; xac1_proto.cli -> xac1_proto.sim (below) is not."""
    found = layer_breaks({("sniffer", "conformance"), ("xac1_proto", "sniffer"),
                          ("xac1_proto.cli", "xac1_proto.sim")})
    assert found == ["sniffer -> conformance", "xac1_proto -> sniffer"]


@pytest.mark.slow  # starts a process
def test_sim_model_loads_no_io():
    """``import xac1_proto.sim.model`` (the sans-IO device model) loads no serial port, socket, thread,
    runner or URL handler, and registers no URL handler with pyserial."""
    modules = loaded_after("import xac1_proto.sim.model")
    assert "xac1_proto.sim.model" in modules
    assert [m for m in forbidden(modules) if not m.startswith("xac1_proto.sim")] == []
    assert [m for m in modules if m in {"xac1_proto.sim.runner", "xac1_proto.sim.cli"}] == []
