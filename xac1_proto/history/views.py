"""What ``xac1 history`` shows, as rows (one dict a row, columns in order), and the three ways to print
them: rich tables, JSON, CSV.

How this works: each view (``list_rows``, ``unit_rows``, ``firmware_rows``, ``compare_rows``,
``show_rows``) turns stored runs into plain rows; ``emit`` prints rows in the chosen format, so the
table, the JSON array and the CSV always hold the same values. A list value (the failed rules) is a
JSON array, and ``a b c`` in a table or CSV cell.
"""

from __future__ import annotations

import csv
import json
import sys
from collections import Counter
from collections.abc import Sequence
from typing import Any, TextIO

from .model import CONFORMS, RunRecord
from .store import StoredRun

Row = dict[str, Any]
FORMATS = ("text", "json", "csv")


def when(run: RunRecord) -> str:
    """When the run started, in this machine's local time, with its UTC offset."""
    return run.started.astimezone().isoformat(timespec="seconds")


def list_rows(runs: Sequence[StoredRun]) -> list[Row]:
    return [{"run": s.id, "started": when(s.run), "kind": s.run.kind, "station": s.run.station,
             "operator": s.run.operator, "port": s.run.port, "unit": s.run.unit, "firmware": s.run.firmware,
             "verdict": s.run.verdict, "exit_status": s.run.exit_status, "failed_rules": s.run.failed_rules,
             "fleet": s.run.fleet}
            for s in runs]


def unit_name(run: RunRecord) -> str:
    """The unit's id, or its port where the run was given no id."""
    return run.unit or f"(port {run.port})"


def unit_rows(runs: Sequence[StoredRun]) -> list[Row]:
    """Each unit's last run (runs come oldest first)."""
    last: dict[str, StoredRun] = {}
    count: Counter[str] = Counter()
    for s in runs:
        last[unit_name(s.run)] = s
        count[unit_name(s.run)] += 1
    return [{"unit": name, "last_run": s.id, "started": when(s.run), "station": s.run.station,
             "firmware": s.run.firmware, "verdict": s.run.verdict, "exit_status": s.run.exit_status,
             "failed_rules": s.run.failed_rules, "runs": count[name]}
            for name, s in sorted(last.items())]


def firmware_rows(runs: Sequence[StoredRun]) -> list[Row]:
    """Per firmware version: runs, how many conformed, the pass rate, the rules failed and how often."""
    by: dict[str, list[RunRecord]] = {}
    for s in runs:
        by.setdefault(s.run.firmware or "unknown", []).append(s.run)
    rows = []
    for firmware, group in sorted(by.items()):
        passed = sum(1 for r in group if r.verdict == CONFORMS)
        rules = Counter(rule for r in group for rule in r.failed_rules)
        rows.append({"firmware": firmware, "runs": len(group), "conforming": passed,
                     "pass_rate": round(passed / len(group), 3),
                     "failed_rules": [f"{rule} ({n})" for rule, n in rules.most_common()]})
    return rows


def compare_rows(a: StoredRun, b: StoredRun) -> list[Row]:
    """The checks whose outcome (or violation codes) differ between the two runs, in run order; a
    check one run did not have is ``-`` there."""
    before = {c.name: c for c in a.run.checks}
    after = {c.name: c for c in b.run.checks}
    rows = []
    for name in dict.fromkeys([*before, *after]):
        x, y = before.get(name), after.get(name)
        if x is not None and y is not None and (x.outcome, x.codes) == (y.outcome, y.codes):
            continue
        either = y or x
        rows.append({"check": name, "rule": either.rule if either else "",
                     f"run {a.id}": x.outcome if x else "-", f"run {b.id}": y.outcome if y else "-",
                     f"codes {a.id}": list(x.codes) if x else [],
                     f"codes {b.id}": list(y.codes) if y else []})
    return rows


def show_rows(s: StoredRun) -> list[Row]:
    return [{"check": c.name, "outcome": c.outcome, "codes": list(c.codes), "rule": c.rule,
             "message": c.message, "information": c.info} for c in s.run.checks]


def run_object(s: StoredRun) -> Row:
    """One run in full, for ``show --format json``."""
    return {"run": s.id, **s.run.to_json(), "failed_rules": s.run.failed_rules}


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, list):
        return " ".join(str(v) for v in value)
    return str(value)


def emit(rows: Sequence[Row], fmt: str, title: str = "", empty: str = "nothing recorded",
         out: TextIO | None = None) -> None:
    """Print ``rows`` as a rich table (``text``), a JSON array or CSV (header line first)."""
    out = out or sys.stdout
    if fmt == "json":
        json.dump(list(rows), out, indent=1, ensure_ascii=False)
        out.write("\n")
    elif fmt == "csv":
        columns = list(rows[0]) if rows else []
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(columns)
        writer.writerows([_cell(r[c]) for c in columns] for r in rows)
    else:
        _table(rows, title, empty, out)


def console(out: TextIO) -> Any:
    from rich.console import Console

    terminal = Console(file=out, highlight=False)
    return terminal if terminal.is_terminal else Console(file=out, highlight=False, width=200)


def _table(rows: Sequence[Row], title: str, empty: str, out: TextIO) -> None:
    from rich.table import Table

    con = console(out)
    if not rows:
        con.print(empty, markup=False)
        return
    table = Table(title=title or None, title_justify="left")
    for column in rows[0]:
        table.add_column(column.replace("_", " "), overflow="fold")
    for row in rows:
        table.add_row(*(_styled(k, v) for k, v in row.items()))
    con.print(table)


def _styled(column: str, value: Any) -> Any:
    from rich.text import Text

    text = _cell(value)
    if column == "verdict":
        return Text(text, style="green" if text == CONFORMS else "red")
    return Text(text)
