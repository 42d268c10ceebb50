"""Shell completion for ``xac1`` (issue 40 item 12): argcomplete's protocol, driven for real.

The shell's hook runs ``xac1`` with ``_ARGCOMPLETE`` and ``COMP_LINE`` set; ``xac1`` answers with the
completions and ends. Only then is argcomplete imported, and a subcommand's module only once its name is
typed in full, so ``xac1 --help`` and the completion of a subcommand's name stay as quick as before."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from xac1_proto.cli import COMMANDS

pytestmark = pytest.mark.slow  # starts processes (bash, xac1)

BIN = Path(sys.executable).parent


def _env(**extra: str) -> dict[str, str]:
    return {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", **extra}


# The child: the console script's main, its modules listed as argcomplete ends the process.
CHILD = """
import os, sys
real_exit, listing = os._exit, sys.argv[1]
def listed_exit(code):
    with open(listing, "w") as f:
        f.write("\\n".join(sorted(sys.modules)))
    real_exit(code)
os._exit = listed_exit
sys.argv = ["xac1"]
from xac1_proto.entry import main
main()
"""


def complete(line: str, tmp_path: Path) -> tuple[list[str], set[str]]:
    """What ``xac1`` answers for ``line`` (the cursor at its end) and the modules it had imported."""
    out, modules = tmp_path / "completions", tmp_path / "modules"
    done = subprocess.run([sys.executable, "-c", CHILD, str(modules)], capture_output=True, text=True,
                          timeout=60, env=_env(_ARGCOMPLETE="1", COMP_LINE=line, COMP_POINT=str(len(line)),
                                               _ARGCOMPLETE_IFS="\n", _ARGCOMPLETE_STDOUT_FILENAME=str(out)))
    assert done.returncode == 0, done.stderr[-2000:]
    return out.read_text().split("\n"), set(modules.read_text().split("\n"))


def test_a_subcommand_name_completes_without_importing_any_subcommand(tmp_path):
    """``xac1 de<TAB>`` offers ``decode``, and no subcommand's module is imported to say so."""
    words, imported = complete("xac1 de", tmp_path)
    assert [w.strip() for w in words] == ["decode"]
    assert [c.module for c in COMMANDS.values() if c.module in imported] == []


def test_a_typed_subcommand_completes_its_options_and_choices(tmp_path):
    """Once the subcommand is typed, its own options and an option's choices complete; only that
    subcommand's module is imported."""
    words, imported = complete("xac1 replay --dr", tmp_path)
    assert [w.strip() for w in words] == ["--dry-run"]
    assert [c.module for c in COMMANDS.values() if c.module in imported] == ["sniffer.replay_cli"]
    words, _ = complete("xac1 decode -f ", tmp_path)
    assert {"text", "jsonl", "summary"} <= {w.strip() for w in words}


def test_help_does_not_import_argcomplete():
    """``xac1 --help`` imports neither argcomplete nor any subcommand: completion costs it nothing."""
    code = ("import contextlib, io, sys\nfrom xac1_proto.cli import main\nout = io.StringIO()\n"
            "with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):\n    main(['--help'])\n"
            "assert 'decode' in out.getvalue()\nprint('\\n'.join(sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                          env=_env())
    assert done.returncode == 0, done.stderr[-2000:]
    imported = set(done.stdout.split())
    assert "xac1_proto.cli" in imported and "argcomplete" not in imported
    assert [c.module for c in COMMANDS.values() if c.module in imported] == []


def test_bash_with_the_registered_script_completes_xac1(tmp_path):
    """The script the README gives for bash (``register-python-argcomplete xac1``), sourced in a real
    bash, fills ``COMPREPLY`` for ``xac1 de<TAB>`` and ``xac1 sim --devi<TAB>``."""
    script = subprocess.run([BIN / "register-python-argcomplete", "xac1"], capture_output=True, text=True,
                            timeout=60, check=True).stdout
    (tmp_path / "xac1.bash").write_text(script)
    probe = ('source "$1"\n'
             'ask() { COMP_LINE="$*"; COMP_POINT=${#COMP_LINE}; COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1));\n'
             '  _python_argcomplete xac1 "${COMP_WORDS[-1]}" "${COMP_WORDS[-2]}";\n'
             '  printf "%s|" "${COMPREPLY[@]}"; echo; }\n'
             'ask xac1 de\n'
             'ask xac1 sim --devi\n')
    done = subprocess.run(["bash", "-c", probe, "bash", str(tmp_path / "xac1.bash")], capture_output=True,
                          text=True, timeout=60, cwd=tmp_path, env=_env())
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert [[w.strip() for w in line.split("|") if w] for line in lines] == [["decode"], ["--deviation"]]
