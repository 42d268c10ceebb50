"""The acceptance history against the real things: SQLite files and a real PostgreSQL server
(``postgres`` fixture, one for the session), written by real ``xac1`` processes.

The issue's "Done when": two conformance runs of different units (one conforming, one not: the
simulator with a deviation) and a fleet run appear in ``xac1 history list`` with the right verdicts and
failing rules, in SQLite and in PostgreSQL; ``compare`` names the rule that changed; a run with the
store unreachable keeps its verdict and exit status and is synced later. Also: two writers at once
never lose or mix a run, and a PostgreSQL store of the first schema is migrated in place.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import sqlalchemy as sa
from conftest import ROOT, xac1

from xac1_proto.history import spool
from xac1_proto.history.migrations import HEAD
from xac1_proto.history.store import Store, migrate, normalise

GOOD = "xac1sim://?time_scale=0"
BAD = "xac1sim://?time_scale=0&deviation=wrong-reset-answer"  # fails reset_clears_alarm
QUICK = ["--examples", "3"]
BROKEN_RULE = "reset_clears_alarm"


def store_for(kind: str, request: pytest.FixtureRequest, tmp_path: Path) -> tuple[str, str]:
    """A fresh store of ``kind`` and a URL of the same kind that cannot be reached."""
    if kind == "sqlite":
        blocker = tmp_path / "not-a-folder"
        blocker.write_text("")
        return f"sqlite:///{tmp_path / 'plant.sqlite'}", str(blocker / "history.sqlite")
    server = request.getfixturevalue("postgres")
    closed = server.port + 1 if server.port < 65535 else server.port - 1
    return server.database(), f"postgresql://{server.user}@127.0.0.1:{closed}/nowhere"


def start(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "xac1_proto", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def finish(proc: subprocess.Popen[str]) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=120)
    return proc.returncode, out, err


def listed(url: str, *filters: str) -> list[dict[str, object]]:
    r = xac1("history", "list", "--history", url, "-f", "json", *filters)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["sqlite", "postgresql"])
def test_done_when(kind, request, tmp_path, private_history):
    """Two single runs (SN-1 conforms, SN-2 does not), a fleet of two (UNIT-A, UNIT-B) and a run whose
    store is unreachable all run at once against one fresh store: every run is listed with its verdict,
    exit status and failing rules, the fleet's two with one fleet id; --rule finds the failing units;
    compare names the rule that changed; the unreachable run keeps exit 1, says so in one line, and
    ``xac1 history sync`` sends it later."""
    url, unreachable = store_for(kind, request, tmp_path)
    rack = tmp_path / "rack.txt"
    rack.write_text(f"{GOOD} UNIT-A\n{BAD} UNIT-B\n")
    procs = {
        "SN-1": start(["conformance", "--port", GOOD, *QUICK, "--unit-id", "SN-1", "--operator", "ann",
                       "--station", "rack-7", "--history", url, "--report", "sn1.html"], tmp_path),
        "SN-2": start(["conformance", "--port", BAD, *QUICK, "--unit-id", "SN-2", "--history", url],
                      tmp_path),
        "fleet": start(["conformance", "--ports", str(rack), *QUICK, "--history", url], tmp_path),
        "SN-3": start(["conformance", "--port", BAD, *QUICK, "--unit-id", "SN-3", "--history", unreachable],
                      tmp_path),
    }
    done = {name: finish(p) for name, p in procs.items()}
    assert [done[n][0] for n in ("SN-1", "SN-2", "fleet", "SN-3")] == [0, 1, 1, 1], done
    for name in ("SN-1", "SN-2", "fleet"):
        assert "history:" not in done[name][2], done[name][2]
    warning = [line for line in done["SN-3"][2].splitlines() if "history:" in line]
    assert len(warning) == 1 and "xac1 history sync" in warning[0], done["SN-3"][2]
    assert done["SN-3"][1].splitlines()[-1].startswith("xac1 conformance: DOES NOT CONFORM")

    runs = {r["unit"]: r for r in listed(url)}
    assert set(runs) == {"SN-1", "SN-2", "UNIT-A", "UNIT-B"}
    for unit, verdict, status in (("SN-1", "CONFORMS", 0), ("SN-2", "DOES NOT CONFORM", 1),
                                  ("UNIT-A", "CONFORMS", 0), ("UNIT-B", "DOES NOT CONFORM", 1)):
        assert (runs[unit]["verdict"], runs[unit]["exit_status"], runs[unit]["firmware"]) == (verdict, status,
                                                                                                "100")
        assert (BROKEN_RULE in runs[unit]["failed_rules"]) == (status == 1), runs[unit]
    assert runs["UNIT-A"]["fleet"] == runs["UNIT-B"]["fleet"] and runs["UNIT-A"]["fleet"]
    assert runs["SN-1"]["fleet"] is None and (runs["SN-1"]["station"], runs["SN-1"]["operator"]) == ("rack-7",
                                                                                                   "ann")
    assert sorted(r["unit"] for r in listed(url, "--rule", BROKEN_RULE)) == ["SN-2", "UNIT-B"]
    assert [r["unit"] for r in listed(url, "--fleet", str(runs["UNIT-A"]["fleet"]))] in (
        ["UNIT-A", "UNIT-B"], ["UNIT-B", "UNIT-A"])

    r = xac1("history", "compare", str(runs["SN-1"]["run"]), str(runs["SN-2"]["run"]), "--history", url,
             "-f", "json")
    changed = {row["check"]: row for row in json.loads(r.stdout)}
    assert BROKEN_RULE in changed and changed[BROKEN_RULE][f"run {runs['SN-1']['run']}"] == "PASS"
    assert changed[BROKEN_RULE][f"run {runs['SN-2']['run']}"] == "FAIL"
    r = xac1("history", "show", str(runs["SN-1"]["run"]), "--history", url, "-f", "json")
    shown = json.loads(r.stdout)
    assert [what for what, path in shown["files"]] == ["report"] and shown["files"][0][1].endswith("sn1.html")
    assert shown["settings"]["motion"] == "allowed" and len(shown["checks"]) > 90

    assert len(spool.waiting()) == 1
    r = xac1("history", "sync", "--history", url)
    assert r.returncode == 0 and "1 spooled runs sent" in r.stdout, r.stdout + r.stderr
    (late,) = listed(url, "--unit", "SN-3")
    assert (late["verdict"], late["exit_status"]) == ("DOES NOT CONFORM", 1) and spool.waiting() == []


WRITER = """
import datetime as dt, sys, time
from pathlib import Path
from xac1_proto.history.model import CheckRecord, RunRecord
from xac1_proto.history.store import Store
url, who, n, go = sys.argv[1], sys.argv[2], int(sys.argv[3]), Path(sys.argv[4])
while not go.exists():
    time.sleep(0.01)
for i in range(n):
    t = dt.datetime.now().astimezone()
    run = RunRecord(kind="fuzz", started=t, ended=t, verdict="CONFORMS", exit_status=0, unit=f"{who}-{i}",
                    checks=tuple(CheckRecord(name=f"{who}-{i}-{k}", outcome="PASS") for k in range(20)))
    with Store.open(url) as store:
        store.add(run)
"""


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["sqlite", "postgresql"])
def test_two_writers_at_once(kind, request, tmp_path):
    """Two processes recording runs at the same moment into one store that neither has opened before
    (both migrate it at once): every run is there once, with exactly its own twenty checks."""
    url, _ = store_for(kind, request, tmp_path)
    go, n = tmp_path / "go", 15
    writers = [subprocess.Popen([sys.executable, "-c", WRITER, url, who, str(n), str(go)], cwd=ROOT,
                                stderr=subprocess.PIPE, text=True) for who in ("A", "B")]
    go.write_text("")
    for w in writers:
        _, err = w.communicate(timeout=120)
        assert w.returncode == 0, err
    with Store.open(url) as store:
        runs = store.runs()
    assert sorted(s.run.unit or "" for s in runs) == sorted(f"{w}-{i}" for w in "AB" for i in range(n))
    for s in runs:
        assert [c.name for c in s.run.checks] == [f"{s.run.unit}-{k}" for k in range(20)]


@pytest.mark.slow
def test_postgresql_migration_from_the_first_schema(postgres):
    """A PostgreSQL store of the first schema, with a run in it, is upgraded in place: the old run is
    kept, the store ends at the head revision and matches ``schema.py`` exactly."""
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from xac1_proto.history import schema

    url = postgres.database()
    engine = sa.create_engine(normalise(url))
    with engine.begin() as conn:
        migrate(conn, "0001")
        conn.execute(sa.text(
            "INSERT INTO runs (uid, kind, started, ended, unit, verdict, verdict_line, exit_status, "
            "kit_version, command_line) VALUES ('old1', 'conformance', '2026-01-05 08:00:00+00', "
            "'2026-01-05 08:01:00+00', 'SN-0001', 'CONFORMS', '', 0, '0.0.9', '')"))
    with Store.open(url) as store:
        (old,) = store.runs()
    assert (old.run.uid, old.run.unit, old.run.readings) == ("old1", "SN-0001", None)
    with engine.connect() as conn:
        assert conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar() == HEAD
        assert compare_metadata(MigrationContext.configure(conn), schema.metadata) == []
    engine.dispose()


DRAWN = """(() => Object.fromEntries(["per-day", "per-firmware", "per-rule"].map(id => {
  const gd = document.getElementById(id);
  return [id, {laid_out: !!gd._fullLayout, bars: gd.querySelectorAll(".barlayer .point").length,
               traces: gd.data.map(t => t.name), ys: gd.data.map(t => Array.from(t.y))}];
})))()"""


@pytest.mark.slow
@pytest.mark.requires_tool("chromium")
def test_trend_page_draws_in_chromium(tmp_path):
    """``xac1 history report --html``'s page, opened in headless Chromium, draws its three plots (a bar
    for each day and verdict, each firmware version, each day a rule failed) with no console error and no
    request: plotly is inlined."""
    import datetime as dt

    from session_report_browser import Browser

    from xac1_proto.history.model import CheckRecord, RunRecord

    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    t0 = dt.datetime(2026, 11, 2, 9, tzinfo=dt.timezone.utc)
    with Store.open(url) as store:
        for day, firmware, failed in ((0, "102", True), (0, "102", False), (1, "103", False)):
            when = t0 + dt.timedelta(days=day)
            store.add(RunRecord(kind="conformance", started=when, ended=when, firmware=firmware,
                                verdict="DOES NOT CONFORM" if failed else "CONFORMS", exit_status=int(failed),
                                checks=(CheckRecord(name=BROKEN_RULE,
                                                    outcome="FAIL" if failed else "PASS"),)))
    page_file = tmp_path / "trend.html"
    r = xac1("history", "report", "--history", url, "--html", str(page_file))
    assert r.returncode == 0, r.stderr
    browser = Browser()
    try:
        page = browser.open(page_file)
        drawn = page.evaluate(DRAWN)
        assert page.problems() == [] and page.requests() == []
    finally:
        browser.close()
    assert all(d["laid_out"] for d in drawn.values()), drawn
    assert (drawn["per-day"]["ys"], drawn["per-day"]["bars"]) == ([[1, 1], [1, 0]], 4)  # a bar a day a trace
    assert (drawn["per-firmware"]["ys"], drawn["per-firmware"]["bars"]) == ([[50, 100]], 2)
    assert (drawn["per-rule"]["traces"], drawn["per-rule"]["ys"]) == ([BROKEN_RULE], [[1, 0]])
    assert drawn["per-rule"]["bars"] == 2
