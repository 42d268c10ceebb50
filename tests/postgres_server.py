"""A real PostgreSQL server for the history tests: ``initdb`` and ``postgres`` from the Debian
``postgresql`` package, on a temporary folder and a free port, stopped however the session ends.

How this works: the binaries are found on PATH, else in the newest ``/usr/lib/postgresql/<ver>/bin``
(where Debian puts them, off PATH). PostgreSQL refuses to run as root, so under root both run as the
``postgres`` system user, in a folder of its own under the system's temporary folder (the pytest
folders of root are closed to it). The server runs in the foreground as a child of the test process and
dies with it (Linux's parent-death signal), so not even a killed session leaves one behind; the
fixture stops it with SIGINT (a fast shutdown) and removes the folder. Each test gets a database of its
own (``Postgres.database()``).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import pwd
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

PACKAGE = "postgresql"
PR_SET_PDEATHSIG = 1


def binaries() -> Path | None:
    """The folder holding initdb and postgres, or None when PostgreSQL is not installed."""
    on_path = shutil.which("initdb")
    if on_path and shutil.which("postgres"):
        return Path(on_path).parent
    found = []
    for d in Path("/usr/lib/postgresql").glob("*/bin"):
        m = re.fullmatch(r"\d+(?:\.\d+)?", d.parent.name)
        if m and (d / "initdb").is_file() and (d / "postgres").is_file():
            found.append((float(d.parent.name), d))
    return max(found)[1] if found else None


def missing() -> str | None:
    """Why no server can be started (naming the Debian package), or None."""
    if binaries() is None:
        return (f"PostgreSQL's initdb and postgres not found on PATH nor in /usr/lib/postgresql/*/bin "
                f"(Debian package {PACKAGE}: sudo apt-get install {PACKAGE})")
    if os.geteuid() == 0:
        try:
            pwd.getpwnam("postgres")
        except KeyError:
            return f"running as root and there is no postgres user (Debian package {PACKAGE} makes it)"
    return None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _as_server_user() -> Callable[[], None]:
    """The child's set-up: drop to the postgres user when root, then die with the test process."""
    user = pwd.getpwnam("postgres") if os.geteuid() == 0 else None

    def setup() -> None:
        if user is not None:
            os.setgid(user.pw_gid)
            os.setuid(user.pw_uid)
        with contextlib.suppress(OSError, AttributeError):  # after setuid, which clears it
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGINT, 0, 0, 0)

    return setup


@dataclass
class Postgres:
    """A running server: connect as ``user`` on 127.0.0.1:``port``."""

    port: int
    user: str
    folder: Path

    def url(self, database: str = "postgres") -> str:
        return f"postgresql://{self.user}@127.0.0.1:{self.port}/{database}"

    def database(self) -> str:
        """A new empty database; its URL."""
        import psycopg

        name = f"h_{uuid.uuid4().hex[:12]}"
        with psycopg.connect(host="127.0.0.1", port=self.port, user=self.user, dbname="postgres",
                             autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)


def _ready(port: int, user: str) -> bool:
    import psycopg

    try:
        psycopg.connect(host="127.0.0.1", port=port, user=user, dbname="postgres", connect_timeout=1).close()
    except psycopg.OperationalError:
        return False
    return True


@contextlib.contextmanager
def running(timeout: float = 60.0) -> Iterator[Postgres]:
    """Start a server (initdb, then postgres in the foreground); stop it and remove its folder after."""
    bindir = binaries()
    assert bindir is not None, missing()
    folder = Path(tempfile.mkdtemp(prefix="xac1-pg-"))
    data = folder / "data"
    setup = _as_server_user()
    if os.geteuid() == 0:
        user = pwd.getpwnam("postgres")
        os.chown(folder, user.pw_uid, user.pw_gid)
    port, role = _free_port(), "xac1"
    proc: subprocess.Popen[bytes] | None = None
    try:
        subprocess.run([str(bindir / "initdb"), "-D", str(data), "-U", role, "--auth=trust", "-E", "UTF8",
                        "--no-sync"], check=True, capture_output=True, preexec_fn=setup, timeout=timeout,
                       cwd=folder)
        log = open(folder / "server.log", "wb")  # noqa: SIM115 - the server's, closed below
        proc = subprocess.Popen([str(bindir / "postgres"), "-D", str(data), "-p", str(port),
                                 "-k", str(folder),
                                 "-c", "listen_addresses=127.0.0.1", "-c", "fsync=off",
                                 "-c", "synchronous_commit=off", "-c", "full_page_writes=off"],
                                stdout=log, stderr=subprocess.STDOUT, preexec_fn=setup, cwd=folder)
        log.close()
        deadline = time.monotonic() + timeout
        while not _ready(port, role):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"PostgreSQL did not start: {(folder / 'server.log').read_text()[-2000:]}")
            time.sleep(0.1)
        yield Postgres(port, role, folder)
    finally:
        if proc is not None and proc.poll() is None:
            proc.send_signal(signal.SIGINT)  # a fast shutdown: clients cut, nothing to keep
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        shutil.rmtree(folder, ignore_errors=True)
