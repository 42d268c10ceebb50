"""``xac1 history report --html FILE``: the trend of the recorded runs on one offline page.

How this works: the runs are counted per day (runs, and those that did not conform), per firmware
version (pass rate) and per failed rule (per day); each count becomes a plotly figure, embedded as JSON
and drawn by the one inlined copy of plotly.js (as the session report does: nothing is fetched when the
page is opened). The tables below the plots hold the same numbers. Needs plotly (the ``report`` extra).
"""

from __future__ import annotations

import datetime as _dt
import json
from collections import Counter
from collections.abc import Callable, Sequence
from typing import Any

from markupsafe import Markup

from .model import CONFORMS
from .store import StoredRun, shown
from .views import firmware_rows

TOP_RULES = 12  # rules drawn one colour each; the rest are summed as "other rules"
CONFIG: dict[str, Any] = {"responsive": True, "displaylogo": False}


def _day(s: StoredRun) -> str:
    return s.run.started.astimezone().date().isoformat()


def figures(runs: Sequence[StoredRun]) -> dict[str, Any]:
    """The page's figures (plotly's JSON form), by the id of the element that draws each."""
    days = sorted({_day(s) for s in runs})
    return {figure_id: draw(runs, days) for figure_id, draw in _FIGURES.items()}


def _runs_a_day(runs: Sequence[StoredRun], days: list[str]) -> Any:
    """Runs a day, stacked: those that conformed and those that did not."""
    import plotly.graph_objects as go

    ok = Counter(_day(s) for s in runs if s.run.verdict == CONFORMS)
    bad = Counter(_day(s) for s in runs if s.run.verdict != CONFORMS)
    return go.Figure([go.Bar(x=days, y=[ok[d] for d in days], name="conforms", marker_color="#2ca02c"),
                      go.Bar(x=days, y=[bad[d] for d in days], name="did not conform (any other verdict)",
                             marker_color="#d62728")],
                     layout={"title": {"text": "runs a day"}, "barmode": "stack", "height": 360,
                             "xaxis": {"type": "category", "title": {"text": "day"}},
                             "yaxis": {"title": {"text": "runs"}}})


def _pass_rate_per_firmware(runs: Sequence[StoredRun], days: list[str]) -> Any:
    """The share of runs that conformed, per firmware version (0RV's answer)."""
    import plotly.graph_objects as go

    rows = firmware_rows(runs)
    return go.Figure([go.Bar(x=[r["firmware"] for r in rows], y=[100 * r["pass_rate"] for r in rows],
                             text=[f"{r['conforming']} of {r['runs']}" for r in rows],
                             marker_color="#1f77b4", name="pass rate")],
                     layout={"title": {"text": "pass rate per firmware version"}, "height": 360,
                             "xaxis": {"type": "category", "title": {"text": "firmware (0RV)"}},
                             "yaxis": {"title": {"text": "% of runs that conformed"}, "range": [0, 100]}})


def _failed_rules_a_day(runs: Sequence[StoredRun], days: list[str]) -> Any:
    """Failed checks a day, stacked per rule: the TOP_RULES most failed one colour each, the rest summed
    as "other rules"."""
    import plotly.graph_objects as go

    failures = Counter(rule for s in runs for rule in s.run.failed_rules)
    top = [rule for rule, _n in failures.most_common(TOP_RULES)]
    traces = []
    for rule in [*top, "other rules"]:
        count = Counter(_day(s) for s in runs for r in s.run.failed_rules
                        if r == rule or (rule == "other rules" and r not in top))
        if count:
            traces.append(go.Bar(x=days, y=[count[d] for d in days], name=rule))
    return go.Figure(traces, layout={"title": {"text": "failed checks a day, per rule"}, "height": 400,
                                     "barmode": "stack", "xaxis": {"type": "category"},
                                     "yaxis": {"title": {"text": "runs that failed it"}},
                                     "legend": {"orientation": "h", "y": -0.3}})


# The page's figures by the id of the element that draws each, in the page's order.
_FIGURES: dict[str, Callable[[Sequence[StoredRun], list[str]], Any]] = {
    "per-day": _runs_a_day, "per-firmware": _pass_rate_per_firmware, "per-rule": _failed_rules_a_day}


def _script_json(obj: Any) -> Markup:
    """JSON safe inside a ``<script>`` element."""
    return Markup(json.dumps(obj, separators=(",", ":")).replace("<", "\\u003c"))


def page(runs: Sequence[StoredRun], url: str) -> str:
    """The whole page (self-contained HTML)."""
    import plotly.io as pio
    from plotly.offline import get_plotlyjs

    from xac1_proto.pages import render

    drawn = figures(runs) if runs else {}
    failures = Counter(rule for s in runs for rule in s.run.failed_rules)
    return render("history.html.j2", title="XA-C1 acceptance history", store=shown(url), runs=len(runs),
                  first=runs[0].run.started.isoformat(timespec="minutes") if runs else "",
                  last=runs[-1].run.started.isoformat(timespec="minutes") if runs else "",
                  firmware=firmware_rows(runs), rules=failures.most_common(),
                  figure_ids=list(drawn),
                  figures_json=_script_json({k: json.loads(pio.to_json(f)) for k, f in drawn.items()}),
                  config_json=_script_json(CONFIG),
                  plotly_js=Markup(str(get_plotlyjs()).replace("</script", "<\\/script")) if drawn else "",
                  generated=_dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"))
