# PYTHON_ARGCOMPLETE_OK (argcomplete's global completion looks for this mark: xac1_proto/cli/__init__.py)
"""The ``xac1`` console script's entry (``[project.scripts]``, ``python -m xac1_proto``): the signal
policy comes first, before any heavy import.

How this works: the command line is parsed and the subcommand's module imported only after a few tens
of milliseconds of imports (argparse, dataclasses, the subcommand's own). A signal in that time would
kill the process without a word (SIGTERM, SIGHUP) or print a ``KeyboardInterrupt`` traceback (SIGINT).
So ``main`` first sets, with nothing but the interpreter's own ``os`` and ``signal``, a handler for
SIGINT, SIGTERM and SIGHUP that ends the process at once as the README promises for a signal before
work begins: ``xac1: stopped by SIGTERM`` on stderr, exit status 2 (nothing was opened, written or
sent yet, so there is nothing to undo). The dispatcher (``xac1_proto.cli.main``) then installs the
policy proper (``signals.startup``), and each command its own ``OrderlyEnd``.
"""

from __future__ import annotations

import os
import signal
from types import FrameType

_EARLY = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_EXIT_EARLY = 2  # signals.EXIT_EARLY (that module is not imported yet)


def _stopped_early(signum: int, frame: FrameType | None) -> None:
    """A signal while the program loads: one line straight to stderr's descriptor, exit 2."""
    try:
        name = signal.Signals(signum).name
    except ValueError:
        name = f"signal {signum}"
    try:
        os.write(2, f"xac1: stopped by {name}\n".encode())
    finally:
        os._exit(_EXIT_EARLY)


def main() -> int:
    """Install the early signal policy, then run ``xac1`` with the process's arguments."""
    for sig in _EARLY:
        signal.signal(sig, _stopped_early)
    from .cli import main as dispatch

    return dispatch()
