"""Where runs go: the store's URL (``--history URL``, ``XAC1_HISTORY``, else SQLite under the XDG data
folder), ``--no-history``, and the local spool folder. Imports no database library, so a command can
add these options at no cost.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

ENV = "XAC1_HISTORY"
STORE_NAME = "history.sqlite"


def data_dir() -> Path:
    """``$XDG_DATA_HOME/xac1`` (``~/.local/share/xac1`` when XDG_DATA_HOME is unset or not absolute)."""
    base = os.environ.get("XDG_DATA_HOME", "")
    root = Path(base) if base and os.path.isabs(base) else Path.home() / ".local" / "share"
    return root / "xac1"


def default_url() -> str:
    return f"sqlite:///{data_dir() / STORE_NAME}"


def spool_dir() -> Path:
    """Runs that could not reach their store wait here for ``xac1 history sync``."""
    return data_dir() / "spool"


def store_url(option: str | None) -> str:
    """The store named by ``--history`` (``option``), else ``XAC1_HISTORY``, else the default."""
    return option or os.environ.get(ENV) or default_url()


def target(option: str | None, disabled: bool) -> str | None:
    """The store a run is recorded in, or None with ``--no-history``."""
    return None if disabled else store_url(option)


def add_arguments(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--history URL`` and ``--no-history`` (a command that records runs)."""
    p.add_argument("--history", metavar="URL",
                   help=f"record the run in this history store: a SQLite file or sqlite:///FILE, or "
                        f"postgresql://USER@HOST/DB (default: ${ENV}, else "
                        f"$XDG_DATA_HOME/xac1/{STORE_NAME})")
    p.add_argument("--no-history", action="store_true", help="record nothing in the history store")
