"""The history store: a SQLite file or a PostgreSQL database, opened, brought to the kit's schema and
written one run a transaction.

How this works: ``Store.open(url)`` makes a SQLAlchemy engine (a plain path is a SQLite file, created
with its folder on first use; ``postgresql://`` gets the installed driver, psycopg 3 or pg8000) and
reads the store's schema revision (Alembic's ``alembic_version`` table). The kit's head: nothing more to
do. Older, or an empty database: the migrations in ``migrations/versions`` run, under a lock
(SQLite: the write lock ``BEGIN IMMEDIATE`` takes; PostgreSQL: an advisory lock), so two writers
opening a new store at once migrate it once. A revision the kit does not know was written by a newer
kit: ``NewerSchema``, and nothing is written. Writers never mix runs: each run goes in with its checks,
settings and files in one transaction; SQLite runs in WAL mode with a busy timeout, so a writer waits
for another instead of failing. A store that cannot be opened raises ``StoreUnreachable``.
"""

from __future__ import annotations

import datetime as _dt
import importlib.util
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import Connection, Engine, make_url
from sqlalchemy.exc import ArgumentError, DBAPIError, IntegrityError, NoSuchModuleError
from sqlalchemy.pool import NullPool

from ..errors import XAC1Error
from . import schema
from .migrations import HEAD, REVISIONS
from .model import CheckRecord, RunRecord, utc

BUSY_TIMEOUT_S = 30.0  # SQLite: how long a writer waits for another's transaction
CONNECT_TIMEOUT_S = 5  # PostgreSQL: how long to wait for the server before spooling the run
READ_ONLY = "xac1_read_only"  # the execution option of a transaction that only reads
SCRIPT_LOCATION = "xac1_proto.history:migrations"  # Alembic's script_location, inside the package
_LOCK_KEY = 0x78616331  # "xac1": the PostgreSQL advisory lock held while migrating


class HistoryError(XAC1Error):
    """Something about the history store; the message names the store."""


class StoreUnreachable(HistoryError):
    """The store could not be opened or written (no server, no such folder, no driver...)."""


class NewerSchema(HistoryError):
    """The store was made by a newer kit: its schema revision is unknown here; nothing is written."""


def normalise(url: str) -> str:
    """A SQLAlchemy URL: a plain path is a SQLite file; ``postgresql://`` (or ``postgres://``) gets the
    installed driver (psycopg 3, else pg8000)."""
    if "://" not in url:
        return f"sqlite:///{Path(url).expanduser().resolve()}"
    scheme, rest = url.split("://", 1)
    if scheme in ("postgresql", "postgres"):
        driver = "psycopg" if importlib.util.find_spec("psycopg") else "pg8000"
        return f"postgresql+{driver}://{rest}"
    return url


def shown(url: str) -> str:
    """The URL without its password, for messages and the spool."""
    try:
        return make_url(normalise(url)).render_as_string(hide_password=True)
    except ArgumentError:
        return url


def _sqlite_engine(url: sa.URL) -> Engine:
    if url.database and url.database != ":memory:":
        try:
            Path(url.database).parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreUnreachable(f"cannot make the folder of {url.database}: "
                                   f"{exc.strerror or exc}") from None
    engine = sa.create_engine(url, poolclass=NullPool, connect_args={"timeout": BUSY_TIMEOUT_S})

    @event.listens_for(engine, "connect")
    def _connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # the driver's own transactions off: ours begin below
        dbapi_connection.execute("PRAGMA journal_mode=WAL")
        dbapi_connection.execute("PRAGMA foreign_keys=ON")
        dbapi_connection.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")

    @event.listens_for(engine, "begin")
    def _begin(connection: Connection) -> None:
        if connection.get_execution_options().get(READ_ONLY):
            connection.exec_driver_sql("BEGIN")  # a reader takes no write lock (a read-only file too)
        else:
            connection.exec_driver_sql("BEGIN IMMEDIATE")  # the write lock at once: no upgrade deadlock

    return engine


def make_engine(url: str) -> Engine:
    """An engine for ``url``; ``StoreUnreachable`` for a URL no installed driver serves."""
    try:
        parsed = make_url(normalise(url))
        if parsed.get_backend_name() == "sqlite":
            return _sqlite_engine(parsed)
        args = {"connect_timeout": CONNECT_TIMEOUT_S} if parsed.get_backend_name() == "postgresql" else {}
        if parsed.drivername == "postgresql+pg8000":
            args = {"timeout": CONNECT_TIMEOUT_S}
        return sa.create_engine(parsed, poolclass=NullPool, connect_args=args)
    except (ArgumentError, NoSuchModuleError, ImportError) as exc:
        hint = " (pip install 'xac1-proto[postgresql]')" if "postgres" in url else ""
        raise StoreUnreachable(f"{shown(url)}: no driver for this URL{hint}: {exc}") from None


def _revision(conn: Connection) -> str | None:
    if not sa.inspect(conn).has_table("alembic_version"):
        return None
    return conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar()


def _refuse_newer(url: str, revision: str | None) -> None:
    if revision is not None and revision not in REVISIONS:
        raise NewerSchema(f"the history store {shown(url)} has schema revision {revision}, newer than this "
                          f"kit knows (it knows up to {HEAD}): upgrade xac1-proto to write to it; "
                          f"nothing was written")


def migrate(conn: Connection, to: str = "head") -> None:
    """Run the shipped migrations on ``conn`` (inside its transaction) up to revision ``to``."""
    from alembic import command
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", SCRIPT_LOCATION)
    config.attributes["connection"] = conn
    command.upgrade(config, to)


@dataclass(frozen=True)
class StoredRun:
    """A run as read back: its number in this store, and the record."""

    id: int
    run: RunRecord


class Store:
    """One history store, at the kit's schema (see the module docstring)."""

    def __init__(self, url: str, engine: Engine) -> None:
        self.url = url
        self.engine = engine

    @classmethod
    def open(cls, url: str) -> Store:
        """Open (creating a SQLite file, migrating an older schema); ``StoreUnreachable``, ``NewerSchema``."""
        engine = make_engine(url)
        try:
            with engine.connect().execution_options(**{READ_ONLY: True}) as conn:
                revision = _revision(conn)
                conn.rollback()
            _refuse_newer(url, revision)
            if revision != HEAD:
                with engine.begin() as conn:
                    if engine.dialect.name == "postgresql":
                        conn.execute(sa.select(sa.func.pg_advisory_xact_lock(_LOCK_KEY)))
                    revision = _revision(conn)  # another writer may have migrated it meanwhile
                    _refuse_newer(url, revision)
                    if revision != HEAD:
                        migrate(conn)
        except DBAPIError as exc:
            engine.dispose()
            raise StoreUnreachable(f"{shown(url)}: {_reason(exc)}") from None
        return cls(url, engine)

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _transaction(self, read_only: bool = False) -> Iterator[Connection]:
        try:
            with self.engine.connect().execution_options(**{READ_ONLY: read_only}) as conn, conn.begin():
                yield conn
        except IntegrityError:
            raise
        except DBAPIError as exc:
            raise StoreUnreachable(f"{shown(self.url)}: {_reason(exc)}") from None

    # ---- writing ----

    def add(self, run: RunRecord) -> int:
        """Record ``run`` with its checks, settings and files in one transaction; its number here. A run
        already recorded (the same ``uid``: a spooled run synced twice) is not recorded again."""
        try:
            with self._transaction() as conn:
                found = conn.execute(sa.select(schema.runs.c.id).where(schema.runs.c.uid == run.uid)).scalar()
                if found is not None:
                    return int(found)
                return self._insert(conn, run)
        except IntegrityError:  # another writer recorded the same run between our look and our insert
            with self._transaction() as conn:
                return int(conn.execute(sa.select(schema.runs.c.id)
                                        .where(schema.runs.c.uid == run.uid)).scalar_one())

    @staticmethod
    def _insert(conn: Connection, run: RunRecord) -> int:
        row = {name: getattr(run, name) for name in (
            "uid", "kind", "verdict", "verdict_line", "exit_status", "station", "operator", "port", "unit",
            "firmware", "interrupted", "kit_version", "fleet", "command_line", "readings")}
        row.update(started=utc(run.started), ended=utc(run.ended))
        key = conn.execute(sa.insert(schema.runs).values(**row)).inserted_primary_key
        assert key is not None  # an INSERT always has one (SQLite's lastrowid, PostgreSQL's RETURNING)
        run_id = int(key[0])
        if run.checks:
            conn.execute(sa.insert(schema.checks), [
                {"run_id": run_id, "position": i, "name": c.name, "outcome": c.outcome, "rule": c.rule,
                 "topic": c.topic, "codes": " ".join(c.codes), "message": c.message, "info": c.info}
                for i, c in enumerate(run.checks)])
        if run.settings:
            conn.execute(sa.insert(schema.settings),
                         [{"run_id": run_id, "name": k, "value": v} for k, v in run.settings.items()])
        if run.files:
            conn.execute(sa.insert(schema.files),
                         [{"run_id": run_id, "what": what, "path": path} for what, path in run.files])
        return run_id

    # ---- reading ----

    def runs(self, query: Query | None = None) -> list[StoredRun]:
        """The runs ``query`` selects, oldest first, each with its checks, settings and files."""
        q = query or Query()
        r, c = schema.runs, schema.checks
        stmt = sa.select(r).order_by(r.c.started, r.c.id)
        for column, value in ((r.c.unit, q.unit), (r.c.firmware, q.firmware), (r.c.station, q.station),
                              (r.c.kind, q.kind), (r.c.fleet, q.fleet)):
            if value is not None:
                stmt = stmt.where(column == value)
        if q.verdict is not None:
            stmt = stmt.where(sa.func.upper(r.c.verdict) == q.verdict.upper())
        if q.since is not None:
            stmt = stmt.where(r.c.started >= utc(q.since))
        if q.rule is not None:
            padded = sa.literal(" ") + c.c.codes + sa.literal(" ")
            stmt = stmt.where(sa.exists().where(
                c.c.run_id == r.c.id, c.c.outcome.in_(("FAIL", "ERROR")), c.c.info.is_(False),
                sa.or_(c.c.name == q.rule, padded.like(f"% {q.rule} %"))))
        if q.ids is not None:
            stmt = stmt.where(r.c.id.in_(q.ids))
        with self._transaction(read_only=True) as conn:
            rows = conn.execute(stmt).mappings().all()
            return self._complete(conn, rows)

    def run(self, ref: str) -> StoredRun:
        """The run numbered ``ref`` (or whose uid starts with it); ``HistoryError`` when there is none."""
        r = schema.runs
        with self._transaction(read_only=True) as conn:
            if ref.isdigit():
                rows = conn.execute(sa.select(r).where(r.c.id == int(ref))).mappings().all()
            else:
                rows = conn.execute(sa.select(r).where(r.c.uid.like(f"{ref}%"))).mappings().all()
            if len(rows) != 1:
                what = "no run" if not rows else f"{len(rows)} runs"
                raise HistoryError(f"{what} numbered {ref!r} in the history store {shown(self.url)} "
                                   f"(xac1 history list shows the numbers)")
            return self._complete(conn, rows)[0]

    @staticmethod
    def _complete(conn: Connection, rows: Sequence[Any]) -> list[StoredRun]:
        ids = [row["id"] for row in rows]
        checks: dict[int, list[CheckRecord]] = {i: [] for i in ids}
        settings: dict[int, dict[str, str]] = {i: {} for i in ids}
        files: dict[int, list[tuple[str, str]]] = {i: [] for i in ids}
        for chunk in (ids[i:i + 500] for i in range(0, len(ids), 500)):
            c = schema.checks
            for ch in conn.execute(sa.select(c).where(c.c.run_id.in_(chunk))
                                   .order_by(c.c.run_id, c.c.position)).mappings():
                checks[ch["run_id"]].append(CheckRecord(
                    name=ch["name"], outcome=ch["outcome"], rule=ch["rule"], topic=ch["topic"],
                    codes=tuple(ch["codes"].split()), message=ch["message"], info=bool(ch["info"])))
            s = schema.settings
            for st in conn.execute(sa.select(s).where(s.c.run_id.in_(chunk)).order_by(s.c.name)).mappings():
                settings[st["run_id"]][st["name"]] = st["value"]
            f = schema.files
            for fi in conn.execute(sa.select(f).where(f.c.run_id.in_(chunk)).order_by(f.c.id)).mappings():
                files[fi["run_id"]].append((fi["what"], fi["path"]))
        out = []
        for row in rows:
            fields = {k: row[k] for k in row.keys() if k != "id"}  # noqa: SIM118 - a RowMapping
            fields.update(started=utc(row["started"]), ended=utc(row["ended"]),
                          settings=settings[row["id"]], files=tuple(files[row["id"]]),
                          checks=tuple(checks[row["id"]]))
            out.append(StoredRun(row["id"], RunRecord(**fields)))
        return out


@dataclass(frozen=True)
class Query:
    """Which runs to list; None selects any."""

    unit: str | None = None
    firmware: str | None = None
    station: str | None = None
    verdict: str | None = None
    rule: str | None = None  # a failed check's name, or a violation code a failed check showed
    since: _dt.datetime | None = None
    kind: str | None = None
    fleet: str | None = None
    ids: Sequence[int] | None = None


def _reason(exc: DBAPIError) -> str:
    """The driver's own words, on one line."""
    text = str(exc.orig) if exc.orig is not None else str(exc)
    return " ".join(text.split())
