"""The store's tables as the kit writes and reads them (SQLAlchemy Core), one schema for SQLite and
PostgreSQL.

How this works: these ``Table``s describe the newest schema (``migrations/versions``' head); the
migrations build it, step by step, in a store of any older version, and never import this module
(a migration is frozen once released). ``runs`` holds one row a run; ``checks``, ``settings`` and
``files`` hang off it and go with it (``ON DELETE CASCADE``).
"""

from __future__ import annotations

from sqlalchemy import (
                        Boolean,
                        Column,
                        DateTime,
                        ForeignKey,
                        Integer,
                        MetaData,
                        String,
                        Table,
                        Text,
                        UniqueConstraint,
)

metadata = MetaData()

runs = Table(
    "runs", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("uid", String(32), nullable=False),
    Column("kind", String(16), nullable=False),
    Column("started", DateTime(timezone=True), nullable=False, index=True),
    Column("ended", DateTime(timezone=True), nullable=False),
    Column("station", String(200)),
    Column("operator", String(200)),
    Column("port", String(500)),
    Column("unit", String(200), index=True),
    Column("firmware", String(100), index=True),
    Column("verdict", String(60), nullable=False),
    Column("verdict_line", Text, nullable=False),
    Column("exit_status", Integer, nullable=False),
    Column("interrupted", String(20)),
    Column("kit_version", String(40), nullable=False),
    Column("fleet", String(32)),
    Column("command_line", Text, nullable=False),
    Column("readings", String(20)),  # revision 0002
    UniqueConstraint("uid", name="uq_runs_uid"),
)

checks = Table(
    "checks", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("position", Integer, nullable=False),
    Column("name", String(300), nullable=False, index=True),  # index: revision 0002
    Column("outcome", String(20), nullable=False),
    Column("rule", Text, nullable=False),
    Column("topic", String(100), nullable=False),
    Column("codes", Text, nullable=False),  # the violation codes, space-separated
    Column("message", Text, nullable=False),
    Column("info", Boolean, nullable=False),
)

settings = Table(
    "settings", metadata,
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True),
    Column("name", String(100), primary_key=True),
    Column("value", Text, nullable=False),
)

files = Table(
    "files", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("what", String(40), nullable=False),
    Column("path", Text, nullable=False),
)
