"""``xac1 replay --report FILE.html``: the replay side by side, captured against now, as one page.

Rendered by the project's Jinja2 environment (``xac1_proto.pages``, template ``replay.html.j2``, in the
style of the session report: self-contained, nothing fetched) and written atomically (a temporary file
beside the target, then a rename: ``sniffer.report.page.write_page``).
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from xac1_proto.codec import show_bytes
from xac1_proto.pages import render

from .report.page import write_page

if TYPE_CHECKING:
    from .replay_player import LineResult


def _show(answers: Sequence[Any]) -> str:
    return show_bytes(b"".join(a.raw for a in answers)) if answers else ""


def context(files: Sequence[str], fmt: str, results: Sequence[LineResult], summary: dict[str, Any],
            restored: Sequence[str]) -> dict[str, Any]:
    rows = [{"i": r.line.i, "sent": show_bytes(r.line.raw), "expected": _show(r.line.answers),
             "got": _show(r.got), "same": r.same, "skipped": r.skipped,
             "differences": list(r.comparison.differences),
             "violations": list(dict.fromkeys(r.violations))} for r in results]
    return {"title": "XA-C1 replay report", "sources": [(f, fmt) for f in files], "rows": rows,
            "summary": summary, "restore": list(restored),
            "generated": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")}


def write_report(path: str | os.PathLike[str], files: Sequence[str], fmt: str,
                 results: Sequence[LineResult], summary: dict[str, Any], restored: Sequence[str]) -> str:
    """Render and write the page (``restored``: what the restore did, line by line); returns the path
    written (OSError when it cannot be)."""
    write_page(path, render("replay.html.j2", **context(files, fmt, results, summary, restored)))
    return os.fspath(path)
