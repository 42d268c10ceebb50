"""The store's versioned migrations (Alembic), shipped with the kit and run by ``history.store``.

Each file in ``versions/`` is one revision, named ``NNNN_what.py`` with ``revision = "NNNN"``; they run
in order. ``REVISIONS`` lists them without importing Alembic, so opening a store that is up to date
costs no Alembic import; a test checks Alembic reads the same chain.
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
REVISIONS: tuple[str, ...] = tuple(sorted(p.name.split("_", 1)[0]
                                          for p in (HERE / "versions").glob("[0-9]*.py")))
HEAD = REVISIONS[-1]
