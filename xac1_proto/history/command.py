"""What every command that records its runs shares (``xac1 replay``, ``xac1 fuzz``): its history options
and the one way it records a run.

How this works: ``add_arguments`` adds ``--history URL`` / ``--no-history`` (``where``) and who ran what
where: ``--unit-id``, ``--operator``, ``--station``. When the command ends it calls ``record_command_run``
with a function that builds its ``RunRecord`` from ``identity(args)`` (station, operator, unit, kit
version, command line); the run goes to the store the options name (or the spool), and nothing that
recording does, not even a bug in building the record, changes the command's exit status: a failure is
one line on stderr. Imports no database library until a run is recorded.
"""

from __future__ import annotations

import argparse
import shlex
import socket
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .where import add_arguments as where_arguments
from .where import target

if TYPE_CHECKING:
    from .model import RunRecord


def add_arguments(p: argparse.ArgumentParser, what: str) -> None:
    """The history options of a command whose run is ``what`` (``"the replay"``, ``"the fuzz run"``)."""
    where_arguments(p)
    p.add_argument("--unit-id", metavar="TEXT", help="the unit's serial number or asset tag (in the history)")
    p.add_argument("--operator", metavar="NAME", help=f"who ran {what} (in the history)")
    p.add_argument("--station", metavar="TEXT",
                   help="the test station (in the history; default: the host name)")


def identity(args: argparse.Namespace) -> dict[str, Any]:
    """The ``RunRecord`` fields the options and the host give: station, operator, unit, kit version and
    command line."""
    from xac1_proto import __version__

    return {"station": args.station or socket.gethostname(), "operator": args.operator, "unit": args.unit_id,
            "kit_version": __version__, "command_line": shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]])}


def record_command_run(args: argparse.Namespace, program: str,
                       build: Callable[[dict[str, Any]], RunRecord]) -> None:
    """Record ``build(identity(args))`` in the store the options name (nothing with ``--no-history``)."""
    url = target(args.history, args.no_history)
    if url is None:
        return
    try:
        from .recorder import record

        record(build(identity(args)), url, program)
    except Exception as exc:  # noqa: BLE001 - the exit status stands whatever recording does
        print(f"{program}: history: the run could not be recorded: {type(exc).__name__}: {exc}",
              file=sys.stderr, flush=True)
