"""The acceptance history on SQLite, in process: records read back as written, the spool's JSON round
trip, the migrations against the schema, a migration from the first schema, a newer schema refused, an
unreachable store spooled and synced, and ``xac1 history``'s views and formats."""

from __future__ import annotations

import csv
import datetime as dt
import io
import json
import sqlite3
from pathlib import Path

import pytest
import sqlalchemy as sa
from conftest import CAPTURES, budget
from hypothesis import given, settings
from hypothesis import strategies as st

from xac1_proto.cli import main
from xac1_proto.history import spool
from xac1_proto.history.migrations import HEAD, REVISIONS
from xac1_proto.history.model import CheckRecord, RunRecord
from xac1_proto.history.recorder import record
from xac1_proto.history.store import SCRIPT_LOCATION, NewerSchema, Store, StoreUnreachable, migrate
from xac1_proto.history.where import store_url

T0 = dt.datetime(2026, 11, 2, 9, 30, tzinfo=dt.timezone(dt.timedelta(hours=9)))


def a_run(unit: str = "SN-0042", firmware: str = "102", failed: tuple[str, ...] = (),
          **more: object) -> RunRecord:
    broken = "reset_clears_alarm" in failed
    checks = [CheckRecord(name="version_format", outcome="PASS", rule="0RV answers a version",
                          topic="version"),
              CheckRecord(name="reset_clears_alarm", outcome="FAIL" if broken else "PASS",
                          rule="With an alarm latched, 0%C answers 0%C00", topic="alarms",
                          codes=("latch-broken",) if broken else ()),
              CheckRecord(name="homing", outcome="NOT RUN", topic="motion")]
    fields: dict[str, object] = dict(
        kind="conformance", started=T0, ended=T0 + dt.timedelta(seconds=40),
        verdict="DOES NOT CONFORM" if failed else "CONFORMS", exit_status=1 if failed else 0,
        station="rack-7", operator="ann", port="/dev/ttyUSB0", unit=unit, firmware=firmware,
        kit_version="0.1.0", command_line="xac1 conformance", settings={"motion": "allowed"},
        files=(("report", "/reports/a.html"),), checks=tuple(checks))
    fields.update(more)
    return RunRecord(**fields)  # type: ignore[arg-type]


def sqlite_url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'history.sqlite'}"


def history(*args: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(["history", *args])
    out = capsys.readouterr()
    return status, out.out, out.err


def test_a_run_reads_back_as_written(tmp_path):
    """A run recorded with its checks, settings and files reads back equal (times in UTC, the same
    instants); recording the same run again (its uid) keeps one copy."""
    run = a_run(failed=("reset_clears_alarm",))
    with Store.open(sqlite_url(tmp_path)) as store:
        first = store.add(run)
        assert store.add(run) == first
        (got,) = store.runs()
    assert got.id == first and got.run == run
    assert got.run.started.tzinfo is not None and got.run.started == T0
    assert got.run.failed_rules == ["reset_clears_alarm"]


texts = st.text(st.characters(blacklist_categories=("Cs",)), max_size=20)
optional = st.none() | texts
checks = st.builds(CheckRecord, name=texts, outcome=st.sampled_from(["PASS", "FAIL", "ERROR", "SKIP"]),
                   rule=texts, topic=texts, codes=st.lists(texts, max_size=3).map(tuple), message=texts,
                   info=st.booleans())
times = st.datetimes(min_value=dt.datetime(2000, 1, 1), max_value=dt.datetime(2100, 1, 1),
                     timezones=st.sampled_from([dt.timezone.utc, dt.timezone(dt.timedelta(hours=-5))]))
runs = st.builds(RunRecord, kind=st.sampled_from(["conformance", "replay", "fuzz"]), started=times,
                 ended=times,
                 verdict=texts, exit_status=st.integers(0, 4), verdict_line=texts, station=optional,
                 operator=optional, port=optional, unit=optional, firmware=optional, interrupted=optional,
                 kit_version=texts, fleet=optional, command_line=texts, readings=optional,
                 settings=st.dictionaries(texts, texts, max_size=3),
                 files=st.lists(st.tuples(texts, texts), max_size=2).map(tuple),
                 checks=st.lists(checks, max_size=4).map(tuple))


@settings(max_examples=budget(200))
@given(runs)
def test_spool_json_round_trip(run):
    """Any run survives the spool's JSON form unchanged (to_json, json text, from_json)."""
    assert RunRecord.from_json(json.loads(json.dumps(run.to_json()))) == run


def test_unknown_kind_refused():
    """A run's kind is conformance, replay or fuzz; anything else is refused, naming the three."""
    with pytest.raises(ValueError, match="conformance, replay, fuzz"):
        a_run(kind="sniff")


def test_migrations_build_the_schema(tmp_path):
    """The shipped Alembic revisions are the chain the kit knows (without importing Alembic), and a
    store migrated to the head has exactly the tables, columns and indexes ``schema.py`` describes."""
    from alembic.autogenerate import compare_metadata
    from alembic.config import Config
    from alembic.migration import MigrationContext
    from alembic.script import ScriptDirectory

    from xac1_proto.history import schema

    config = Config()
    config.set_main_option("script_location", SCRIPT_LOCATION)
    script = ScriptDirectory.from_config(config)
    assert tuple(sorted(r.revision for r in script.walk_revisions())) == REVISIONS
    assert script.get_current_head() == HEAD
    url = sqlite_url(tmp_path)
    Store.open(url).close()
    engine = sa.create_engine(url)
    with engine.connect() as conn:
        assert compare_metadata(MigrationContext.configure(conn), schema.metadata) == []
    engine.dispose()


def test_migration_from_the_first_schema(tmp_path):
    """A store made by the first schema (revision 0001, a run in it) is upgraded in place when the kit
    opens it: the old run is still there (its readings setting empty), a new run records readings."""
    path = tmp_path / "old.sqlite"
    engine = sa.create_engine(f"sqlite:///{path}")
    with engine.begin() as conn:
        migrate(conn, "0001")
        conn.execute(sa.text(
            "INSERT INTO runs (uid, kind, started, ended, station, unit, firmware, verdict, verdict_line, "
            "exit_status, kit_version, command_line) VALUES ('old1', 'conformance', '2026-01-05 08:00:00', "
            "'2026-01-05 08:01:00', 'rack-1', 'SN-0001', '101', 'CONFORMS', 'CONFORMS: 98 passed', 0, "
            "'0.0.9', 'xac1 conformance')"))
    engine.dispose()
    with Store.open(str(path)) as store:
        store.add(a_run(readings="notice"))
        old, new = store.runs()
    assert (old.run.uid, old.run.unit, old.run.verdict) == ("old1", "SN-0001", "CONFORMS")
    assert old.run.readings is None
    assert old.run.started == dt.datetime(2026, 1, 5, 8, 0, tzinfo=dt.timezone.utc)
    assert new.run.readings == "notice"
    with sqlite3.connect(path) as db:
        assert db.execute("SELECT version_num FROM alembic_version").fetchall() == [(HEAD,)]


def test_newer_schema_is_refused_and_never_written(tmp_path, capsys, private_history):
    """A store whose schema revision this kit does not know is refused with a message naming both
    revisions; recording into it writes nothing there and spools the run (one warning line)."""
    url = sqlite_url(tmp_path)
    with Store.open(url) as store:
        store.add(a_run())
    with sqlite3.connect(tmp_path / "history.sqlite") as db:
        db.execute("UPDATE alembic_version SET version_num = '0099'")
    with pytest.raises(NewerSchema, match=f"revision 0099, newer than this kit knows .*up to {HEAD}"):
        Store.open(url)
    done = record(a_run(unit="SN-9"), url)
    assert done.run_id is None and done.spooled is not None and done.spooled.exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "newer than this kit knows" in err and "xac1 history sync" in err
    with sqlite3.connect(tmp_path / "history.sqlite") as db:
        assert db.execute("SELECT unit FROM runs").fetchall() == [("SN-0042",)]


def test_unreachable_store_spools_and_sync_sends_later(tmp_path, capsys, private_history):
    """A store that cannot be opened (its folder cannot be made) leaves the run in the spool with one
    warning line; ``xac1 history sync`` sends it to a store that can, once, and empties the spool."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    done = record(a_run(unit="SN-7"), f"sqlite:///{blocker / 'sub' / 'h.sqlite'}")
    assert done.spooled is not None and spool.waiting() == [done.spooled]
    assert "cannot make the folder" in capsys.readouterr().err
    good = sqlite_url(tmp_path)
    status, out, _ = history("sync", "--history", good, capsys=capsys)
    assert status == 0 and "1 spooled runs sent" in out and spool.waiting() == []
    status, out, _ = history("list", "--history", good, "-f", "json", capsys=capsys)
    assert [r["unit"] for r in json.loads(out)] == ["SN-7"]


def test_history_cli_unreachable_store_exit_3(tmp_path, capsys):
    """``xac1 history`` on a store it cannot reach exits 3 naming the store; on an unknown run, 2."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    status, _, err = history("list", "--history", str(blocker / "x.sqlite"), capsys=capsys)
    assert status == 3 and "cannot reach the store" in err
    status, _, err = history("show", "7", "--history", sqlite_url(tmp_path), capsys=capsys)
    assert status == 2 and "no run numbered '7'" in err


@pytest.fixture
def filled(tmp_path) -> str:
    """A store with four runs: two units, firmware 102 then 103, one failure fixed by 103."""
    url = sqlite_url(tmp_path)
    with Store.open(url) as store:
        store.add(a_run(unit="SN-1", firmware="102", failed=("reset_clears_alarm",)))
        store.add(a_run(unit="SN-2", firmware="102", started=T0 + dt.timedelta(days=1)))
        store.add(a_run(unit="SN-1", firmware="103", started=T0 + dt.timedelta(days=2), station="rack-9"))
        store.add(a_run(kind="replay", unit="SN-1", verdict="DIFFERENT", exit_status=1,
                        started=T0 + dt.timedelta(days=3), checks=()))
    return url


def test_list_filters_and_json(filled, capsys):
    """``list --format json``: an array of objects with run, started, station, unit, firmware, verdict,
    exit_status, failed_rules; each filter narrows it (unit, firmware, station, since, verdict, rule by
    check name or violation code, kind)."""
    def units(*filters: str) -> list[tuple[int, str]]:
        status, out, _ = history("list", "--history", filled, "-f", "json", *filters, capsys=capsys)
        assert status == 0
        return [(r["run"], r["unit"]) for r in json.loads(out)]

    status, out, _ = history("list", "--history", filled, "-f", "json", capsys=capsys)
    first = json.loads(out)[0]
    assert {"run", "started", "station", "unit", "firmware", "verdict", "exit_status",
            "failed_rules"} <= set(first)
    assert first["failed_rules"] == ["reset_clears_alarm"] and first["verdict"] == "DOES NOT CONFORM"
    assert units() == [(1, "SN-1"), (2, "SN-2"), (3, "SN-1"), (4, "SN-1")]
    assert units("--unit", "SN-1", "--kind", "conformance") == [(1, "SN-1"), (3, "SN-1")]
    assert units("--firmware", "103") == [(3, "SN-1")]
    assert units("--station", "rack-9") == [(3, "SN-1")]
    assert units("--since", "2026-11-04T00:00+09:00") == [(3, "SN-1"), (4, "SN-1")]
    assert units("--verdict", "does not conform") == [(1, "SN-1")]
    assert units("--rule", "reset_clears_alarm") == units("--rule", "latch-broken") == [(1, "SN-1")]
    assert units("--rule", "version_format") == []


def test_compare_units_firmware_views(filled, capsys):
    """``compare`` names the check whose outcome changed; ``units`` each unit's last conformance verdict;
    ``firmware`` the pass rate and failed rules per version; CSV has a header and one line a row."""
    status, out, _ = history("compare", "1", "3", "--history", filled, "-f", "json", capsys=capsys)
    assert status == 0
    assert json.loads(out) == [{"check": "reset_clears_alarm",
                                "rule": "With an alarm latched, 0%C answers 0%C00",
                                "run 1": "FAIL", "run 3": "PASS", "codes 1": ["latch-broken"], "codes 3": []}]
    status, out, _ = history("compare", "1", "3", "--history", filled, capsys=capsys)
    assert "reset_clears_alarm" in out and "FAIL" in out
    status, out, _ = history("units", "--history", filled, "-f", "json", capsys=capsys)
    assert [(u["unit"], u["last_run"], u["verdict"]) for u in json.loads(out)] == [
        ("SN-1", 3, "CONFORMS"), ("SN-2", 2, "CONFORMS")]
    status, out, _ = history("firmware", "--history", filled, "-f", "csv", capsys=capsys)
    rows = list(csv.DictReader(io.StringIO(out)))
    assert [(r["firmware"], r["runs"], r["pass_rate"], r["failed_rules"]) for r in rows] == [
        ("102", "2", "0.5", "reset_clears_alarm (1)"), ("103", "1", "1.0", "")]


def test_show_text_and_since_errors(filled, capsys):
    """``show`` prints who, where, what and every check; a --since that is no date exits 2 saying what
    it takes."""
    status, out, _ = history("show", "1", "--history", filled, capsys=capsys)
    assert status == 0
    for text in ("unit: SN-1", "station: rack-7", "operator: ann", "firmware: 102",
                 "setting: motion: allowed", "file: report: /reports/a.html", "reset_clears_alarm",
                 "NOT RUN"):
        assert text in out, text
    with pytest.raises(SystemExit) as stop:
        main(["history", "list", "--since", "last tuesday"])
    assert stop.value.code == 2 and "12h, 7d, 2w" in capsys.readouterr().err


def test_report_page(filled, tmp_path, capsys):
    """``report --html`` writes one offline page: plotly inlined, the three trend figures with the runs'
    days, firmware versions and failed rules, and the per-firmware table."""
    page = tmp_path / "trend.html"
    status, out, _ = history("report", "--history", filled, "--html", str(page), capsys=capsys)
    assert status == 0 and "3 runs drawn" in out
    html = page.read_text()
    assert "Plotly.newPlot" in html and "https://" not in html.split("<body>")[1].split("<script")[0]
    figures = json.loads(html.split('id="history-figures">')[1].split("</script>")[0])
    assert set(figures) == {"per-day", "per-firmware", "per-rule"}
    assert figures["per-firmware"]["data"][0]["x"] == ["102", "103"]
    assert figures["per-firmware"]["data"][0]["y"] == [50.0, 100.0]
    assert [t["name"] for t in figures["per-rule"]["data"]] == ["reset_clears_alarm"]
    assert "<td>102</td><td>2</td><td>1</td><td>50 %</td><td>reset_clears_alarm (1)</td>" in html


def test_default_store_is_under_xdg_data_home(private_history, monkeypatch):
    """Without --history or XAC1_HISTORY the store is $XDG_DATA_HOME/xac1/history.sqlite, made on first
    use; XAC1_HISTORY names another."""
    done = record(a_run(), store_url(None))
    assert done.run_id == 1 and (private_history / "xac1" / "history.sqlite").is_file()
    monkeypatch.setenv("XAC1_HISTORY", "postgresql://plant@db.example/xac1")
    assert store_url(None) == "postgresql://plant@db.example/xac1"
    assert store_url("other.sqlite") == "other.sqlite"


def test_store_unreachable_error_is_history_error(tmp_path):
    """A URL no installed driver serves is unreachable, naming the store (and the extra to install)."""
    with pytest.raises(StoreUnreachable, match="no driver"):
        Store.open("mysql+nosuchdriver://u@h/db")


def test_a_replay_is_recorded(private_history, capsys):
    """``xac1 replay`` records its run (kind replay): verdict DIFFERENT and exit 1 as printed, the unit
    and station given, firmware from 0RV, and one entry per captured line whose answer differed, with
    the violation codes of the new exchange; ``--no-history`` records nothing."""
    args = ["replay", str(CAPTURES / "recording.jsonl"), "--port", "xac1sim://?time_scale=0",
            "--pace", "fast", "-f", "jsonl", "--unit-id", "SN-5", "--station", "bench-2"]
    assert main([*args, "--no-history"]) == 1
    assert not (private_history / "xac1" / "history.sqlite").exists()
    assert main(args) == 1
    capsys.readouterr()
    with Store.open(store_url(None)) as store:
        (got,) = store.runs()
    run = got.run
    assert (run.kind, run.verdict, run.exit_status, run.unit, run.station, run.firmware) == (
        "replay", "DIFFERENT", 1, "SN-5", "bench-2", "100")
    assert [(c.name, c.outcome) for c in run.checks] == [(f"line {i}", "DIFFERENT") for i in (4, 8, 12, 14)]
    assert run.checks[1].codes == ("alarm-ignored",) and "alarm-instead-of-answer" in run.checks[1].message
