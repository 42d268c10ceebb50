"""The acceptance history: every run of every unit, kept in a database (SQLite by default, PostgreSQL
for a plant), read back with ``xac1 history``.

How this works: a command that judges a device builds a ``RunRecord`` (``model.py``; ``kind``
conformance, replay or fuzz) when it ends and calls ``record(run, url)`` (``recorder.py``), with the URL
from ``where.target`` (``--history``, ``XAC1_HISTORY``, the XDG default; None for ``--no-history``);
``command.py`` holds the options and the recording every such command shares (replay, fuzz).
``store.py`` opens the store through SQLAlchemy Core (``schema.py``), migrating an older one with the
Alembic revisions shipped in ``migrations/``; a store it cannot reach, or of a newer schema, leaves the
run in the local spool (``spool.py``) for ``xac1 history sync``. ``cli.py`` is ``xac1 history``,
``views.py`` its tables and ``trend.py`` its HTML page. Only ``where``, ``command`` and ``model`` load
without SQLAlchemy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .model import CheckRecord, RunRecord
    from .recorder import Recorded, record

__all__ = ["CheckRecord", "RunRecord", "Recorded", "record"]

_LAZY = {"CheckRecord": "model", "RunRecord": "model", "Recorded": "recorder", "record": "recorder"}


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
