"""The session report page: the aggregates rendered through ``xac1_proto.pages.render`` into one
self-contained HTML file (``session.html.j2``; plotly.js, the figures, the data and the page's script
inline; a Content-Security-Policy forbids any request, so the page opens offline and fetches nothing).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from typing import Any

from markupsafe import Markup

from xac1_proto import spec
from xac1_proto.output_file import write_output
from xac1_proto.pages import figures as fragments
from xac1_proto.pages import render

from ..records import Tally
from . import plots
from .aggregate import SessionAggregator


def _script_json(obj: Any) -> Markup:
    """JSON that is safe inside a ``<script>`` element."""
    text = obj if isinstance(obj, str) else json.dumps(obj, separators=(",", ":"), allow_nan=False)
    return Markup(text.replace("<", "\\u003c"))  # JSON outside strings holds no "<"; inside, the escape


def _when(t: float | None) -> str:
    if t is None:
        return "-"
    return _dt.datetime.fromtimestamp(t, _dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + " UTC"


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    if seconds < 1:
        return f"{seconds * 1000:.1f} ms"
    if seconds < 120:
        return f"{seconds:.3f} s"
    return str(_dt.timedelta(seconds=round(seconds)))


def context(agg: SessionAggregator, title: str = "XA-C1 session report") -> dict[str, Any]:
    """Everything the template shows."""
    summary = agg.summary if agg.summary is not None else Tally().summary()
    figures: dict[str, Any] = {}
    if not agg.empty:
        figures["timeline"] = plots.timeline(agg)
        if agg.aggregated:
            figures["activity"] = plots.activity(agg)
        if agg.latency_hist:
            figures["latency-histogram"] = plots.latency_histogram(agg)
            figures["latency-time"] = plots.latency_over_time(agg)
        if agg.positions.items or agg.alarm_marks.items:
            figures["position"] = plots.position(agg)
    figures_json = "{" + ",".join(f"{json.dumps(k)}:{plots.to_json(f)}" for k, f in figures.items()) + "}"
    span = (agg.t_last - agg.t_first) if agg.timed and agg.t_first is not None and agg.t_last is not None \
        else None
    alarms = [{"when": _when(a.x) if agg.timed else f"record #{a.record}", "code": f"{a.code:02X}",
               "meaning": a.meaning, "answered": a.answered or "-", "repeats": a.repeats,
               "reaction": _reaction(a.reaction, a.reaction_after),
               "ended": a.ended or "still latched at the end", "latched": _duration(a.latched_for)}
              for a in agg.alarms]
    data = {"timed": agg.timed, "records": agg.records,
            "codes": {c: {"meaning": v.meaning, "severity": v.severity, "section": v.section}
                      for c, v in spec.VIOLATION_TABLE.items()},
            "counts": {"records": agg.total_records, "kept": len(agg.records),
                       "exchanges": agg.exchange_count, "exchanges_drawn": len(agg.exchanges),
                       "marks": agg.mark_count, "marks_drawn": len(agg.marks)}}
    commands = summary.get("commands", {})
    latency = summary.get("latency_ms", {})
    command_rows = [{"header": h, "frames": n, "answers": summary.get("answers", {}).get(h, 0),
                     "latency": latency.get(h)} for h, n in commands.items()]
    return {
        "title": title, "empty": agg.empty, "sources": agg.sources, "timed": agg.timed,
        "start": _when(agg.t_first), "end": _when(agg.t_last), "span": _duration(span),
        "summary": summary, "verdicts": agg.verdicts(), "command_rows": command_rows,
        "violation_rows": [{"code": c, "count": n, "meaning": spec.VIOLATIONS[c][1],
                            "severity": spec.VIOLATIONS[c][0]}
                           for c, n in summary.get("violations", {}).items()],
        "alarms": alarms, "alarm_count": agg.alarm_count, "aggregated": agg.aggregated,
        "kept": len(agg.records), "total": agg.total_records, "limits": agg.limits,
        "thinned": agg.positions.thinned or agg.latency_points.thinned,
        "figures": list(figures), "deadline_ms": agg.no_answer_timeout * 1000.0,
        "plotly_js": Markup(fragments.plotly_js().replace("</script", "<\\/script")) if figures else "",
        "figures_json": _script_json(figures_json), "data_json": _script_json(data),
        "config_json": _script_json(fragments.CONFIG),
        "generated": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
    }


def _reaction(what: str | None, after: float | None) -> str:
    if what is None:
        return "none seen"
    verdict = "reset" if what == spec.RESET_HEADER else f"ignored: sent {what}"
    return verdict + (f" after {_duration(after)}" if after is not None else "")


def render_page(agg: SessionAggregator, title: str = "XA-C1 session report") -> str:
    return render("session.html.j2", **context(agg, title))


def write_page(path: str | os.PathLike[str], text: str) -> None:
    """Write atomically to the file ``path`` names (through a link, to its target): a temporary file
    beside it, then a rename (no half-written report, never a FIFO or device replaced)."""
    write_output(path, text)
