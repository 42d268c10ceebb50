"""``xac1 history``: read the acceptance history (list, show, compare, units, firmware, report) and
send the spooled runs to their store (sync).

Exit status: 0 done; 2 bad options (an unknown run, a date that is none); 3 the store cannot be read
(unreachable, or of a newer schema); for ``sync``, 3 also when runs are left in the spool.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import re
import sys
from typing import TYPE_CHECKING

from . import where

if TYPE_CHECKING:
    from .store import Query, Store

HELP = "the acceptance history: list, show and compare recorded runs, per unit and firmware; sync the spool"

EXIT_OK, EXIT_USAGE, EXIT_STORE = 0, 2, 3
_RELATIVE = re.compile(r"(\d+)([hdw])")


def since(text: str) -> _dt.datetime:
    """``--since``: a date (2026-11-01), a date and time (2026-11-01T08:00, local unless it says), or a
    span back from now (12h, 7d, 2w)."""
    m = _RELATIVE.fullmatch(text.strip())
    if m:
        hours = int(m.group(1)) * {"h": 1, "d": 24, "w": 24 * 7}[m.group(2)]
        return _dt.datetime.now().astimezone() - _dt.timedelta(hours=hours)
    try:
        when = _dt.datetime.fromisoformat(text.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is no date: give 2026-11-01, 2026-11-01T08:00, or a span "
                                         f"back from now such as 12h, 7d, 2w") from None
    return when if when.tzinfo else when.astimezone()


def _filters(p: argparse.ArgumentParser) -> None:
    p.add_argument("--unit", help="only this unit (its id: --unit-id, or the fleet file's label)")
    p.add_argument("--firmware", help="only this firmware version (what 0RV answered)")
    p.add_argument("--station", help="only runs made at this station")
    p.add_argument("--since", type=since, metavar="WHEN",
                   help="only runs started since WHEN: 2026-11-01, 2026-11-01T08:00, or 12h, 7d, 2w ago")
    p.add_argument("--verdict",
                   help="only runs with this verdict (CONFORMS, 'DOES NOT CONFORM', INCOMPLETE...)")
    p.add_argument("--rule", help="only runs that failed this check (e.g. reset_clears_alarm) or showed this "
                                  "violation code in a failed check (e.g. latch-broken)")
    p.add_argument("--fleet", metavar="ID",
                   help="only the units of this fleet run (its id, as the fleet printed)")
    p.add_argument("--kind", choices=("conformance", "replay", "fuzz"),
                   help="only runs of this command (list: every kind; units, firmware, report: conformance)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)

    def action(name: str, text: str, filters: bool = True, fmt: bool = True) -> argparse.ArgumentParser:
        a = sub.add_parser(name, help=text, description=text)
        a.add_argument("--history", metavar="URL",
                       help=f"the history store (default: ${where.ENV}, else "
                            f"$XDG_DATA_HOME/xac1/{where.STORE_NAME})")
        if filters:
            _filters(a)
        if fmt:
            a.add_argument("--format", "-f", choices=("text", "json", "csv"), default="text",
                           help="a table (text, default), a JSON array, or CSV")
        return a

    action("list", "every recorded run, oldest first, with its verdict and failed rules")
    show = action("show", "one run: who, where, when, the settings, files and every check", filters=False)
    show.add_argument("run", metavar="RUN", help="the run's number (xac1 history list shows it)")
    compare = action("compare", "the checks whose outcome changed between two runs", filters=False)
    compare.add_argument("runs", metavar="RUN", nargs=2, help="two run numbers: before, after")
    action("units", "each unit's last verdict")
    action("firmware", "per firmware version: runs, pass rate and the rules failed")
    report = action("report", "an HTML page of the trend: runs and failures over time, per firmware and "
                              "per rule", fmt=False)
    report.add_argument("--html", metavar="FILE", required=True, help="write the page to FILE")
    action("sync", "send the runs kept in the local spool (their store was unreachable) to the store",
           filters=False, fmt=False)


def run(args: argparse.Namespace) -> int:
    from .store import HistoryError, NewerSchema, Store, StoreUnreachable

    url = where.store_url(args.history)
    try:
        with Store.open(url) as store:
            return _ACTIONS[args.action](store, args)
    except StoreUnreachable as exc:
        print(f"xac1 history: cannot reach the store: {exc}", file=sys.stderr)
        return EXIT_STORE
    except HistoryError as exc:
        print(f"xac1 history: {exc}", file=sys.stderr)
        return EXIT_STORE if isinstance(exc, NewerSchema) else EXIT_USAGE


def _query(args: argparse.Namespace, kind: str | None = None) -> Query:
    from .store import Query

    return Query(unit=args.unit, firmware=args.firmware, station=args.station, verdict=args.verdict,
                 rule=args.rule, since=args.since, kind=args.kind or kind,
                 fleet=args.fleet)


def _list(store: Store, args: argparse.Namespace) -> int:
    from .views import emit, list_rows

    emit(list_rows(store.runs(_query(args))), args.format, "runs")
    return EXIT_OK


def _units(store: Store, args: argparse.Namespace) -> int:
    from .views import emit, unit_rows

    emit(unit_rows(store.runs(_query(args, "conformance"))), args.format,
         "each unit's last run")
    return EXIT_OK


def _firmware(store: Store, args: argparse.Namespace) -> int:
    from .views import emit, firmware_rows

    emit(firmware_rows(store.runs(_query(args, "conformance"))), args.format,
         "per firmware version")
    return EXIT_OK


def _show(store: Store, args: argparse.Namespace) -> int:
    import json

    from .views import console, emit, run_object, show_rows, when

    found = store.run(args.run)
    if args.format == "json":
        json.dump(run_object(found), sys.stdout, indent=1, ensure_ascii=False)
        print()
        return EXIT_OK
    if args.format == "text":
        r = found.run
        con = console(sys.stdout)
        for label, value in (("run", f"{found.id} ({r.kind}, {r.uid})"),
                             ("started", when(r)),
                             ("ended", r.ended.astimezone().isoformat(timespec="seconds")),
                             ("station", r.station),
                             ("operator", r.operator), ("port", r.port), ("unit", r.unit),
                             ("firmware", r.firmware), ("verdict", r.verdict_line or r.verdict),
                             ("exit status", r.exit_status), ("interrupted", r.interrupted),
                             ("fleet", r.fleet), ("kit", r.kit_version), ("command", r.command_line),
                             ("readings", r.readings),
                             *((f"setting: {k}", v) for k, v in r.settings.items()),
                             *((f"file: {what}", path) for what, path in r.files)):
            if value not in (None, ""):
                con.print(f"{label}: {value}", markup=False, highlight=False)
    emit(show_rows(found), args.format, "checks", "no check was recorded")
    return EXIT_OK


def _compare(store: Store, args: argparse.Namespace) -> int:
    from .views import compare_rows, emit

    a, b = (store.run(ref) for ref in args.runs)
    emit(compare_rows(a, b), args.format, f"run {a.id} -> run {b.id}: the checks that changed",
         f"run {a.id} -> run {b.id}: no check changed")
    return EXIT_OK


def _report(store: Store, args: argparse.Namespace) -> int:
    from xac1_proto.output_file import OutputFileError, write_output

    from .trend import page

    runs = store.runs(_query(args, "conformance"))
    try:
        write_output(args.html, page(runs, store.url))
    except (OSError, OutputFileError) as exc:
        print(f"xac1 history: cannot write {args.html}: {getattr(exc, 'strerror', None) or exc}",
              file=sys.stderr)
        return EXIT_USAGE
    print(f"xac1 history: {len(runs)} runs drawn in {args.html}")
    return EXIT_OK


def _sync(store: Store, args: argparse.Namespace) -> int:
    from .spool import sync, waiting
    from .store import shown

    done = sync(store)
    for path, why in done.unreadable:
        print(f"xac1 history: cannot read {path} ({why}); left in the spool", file=sys.stderr)
    left = len(waiting())
    print(f"xac1 history: {len(done.sent)} spooled runs sent to {shown(store.url)}"
          + (f"; {left} left in {where.spool_dir()}" if left else ""))
    return EXIT_STORE if left else EXIT_OK


_ACTIONS = {"list": _list, "show": _show, "compare": _compare, "units": _units, "firmware": _firmware,
            "report": _report, "sync": _sync}
