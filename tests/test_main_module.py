"""``python -m xac1_proto`` (``xac1_proto/__main__.py``) is the ``xac1`` console script, run in-process
here (the process-level runs are in the slow set)."""

from __future__ import annotations

import importlib
import signal
import sys

import pytest

import xac1_proto

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@pytest.mark.parametrize(("argv", "status", "out"), [
    (["--version"], 0, f"xac1 {xac1_proto.__version__}\n"),
    (["parse", "--role", "command", "0RV\\r\\n"], 0, "0RV command"),
    (["parse", "--role", "command", "ORV\\r\\n"], 2, "letter-o"),
])
def test_python_dash_m_runs_the_console_script(argv, status, out, monkeypatch, capsys):
    """``python -m xac1_proto ARGS`` exits with the command's status and prints what ``xac1 ARGS``
    prints, on stdout or stderr (the entry point then ignores late signals: restored here for the test
    process)."""
    monkeypatch.setattr(sys, "argv", ["xac1", *argv])
    handlers = {s: signal.getsignal(s) for s in SIGNALS}
    try:
        with pytest.raises(SystemExit) as ended:
            # the import runs the module as ``-m`` does (runpy needs a loader's ``get_code``, which pytest's
            # assertion rewriting loader lacks where it claims the package: an egg-info in the checkout)
            importlib.import_module("xac1_proto.__main__")
    finally:
        for s, h in handlers.items():
            signal.signal(s, h)
    assert ended.value.code == status
    printed = capsys.readouterr()
    assert out in printed.out + printed.err
