"""Plotly fragments any report page embeds: a histogram of answer turnaround per command, a stacked bar
of outcomes per group, and plotly.js itself to inline once in a page.

How this works. Each fragment is a ``<div>`` and its script drawn by ``plotly.io.to_html`` without
plotly.js; the page adds ``plotly_js()`` once. The conformance report and the session report
(``sniffer.report``) both use these, so they live here, below both. Importing this module imports plotly:
only the reports need it (the ``report`` extra).
"""

from __future__ import annotations

import html
from typing import Any, Final

import plotly.graph_objects as go
import plotly.io as pio

from .. import spec

CONFIG: Final[dict[str, Any]] = {"responsive": True, "scrollZoom": True, "displaylogo": False}
OUTCOME_COLOUR: Final = {"passed": "#2ca02c", "failed": "#d62728", "skipped": "#bcbd22", "error": "#7f0000"}


def turnaround_histogram(latencies_ms: dict[str, list[float]], title: str = "Answer turnaround",
                         deadline_ms: float | None = spec.NO_ANSWER_TIMEOUT_S * 1000.0) -> str:
    """An HTML fragment (a ``<div>`` and its script; plotly.js is not included: the page adds it once
    with ``plotly_js()``) with a histogram of turnaround per command."""
    traces = [go.Histogram(x=values, name=header, opacity=0.75)
              for header, values in sorted(latencies_ms.items())]
    fig = go.Figure(data=traces, layout={"title": {"text": html.escape(title)}, "barmode": "overlay",
                                         "height": 320, "xaxis": {"title": {"text": "ms"}},
                                         "yaxis": {"title": {"text": "answers"}}})
    if deadline_ms is not None:
        fig.add_vline(x=deadline_ms, line={"color": "#b00020", "dash": "dash"},
                      annotation_text=f"deadline {deadline_ms:g} ms")
    return str(pio.to_html(fig, full_html=False, include_plotlyjs=False, config=CONFIG))


def group_summary(groups: dict[str, dict[str, int]], title: str = "Checks per group") -> str:
    """An HTML fragment (as ``turnaround_histogram``): one stacked bar per group (e.g. conformance
    topic) of its outcome counts (``{"framing": {"passed": 9, "failed": 1}}``)."""
    outcomes = sorted({o for counts in groups.values() for o in counts},
                      key=lambda o: list(OUTCOME_COLOUR).index(o) if o in OUTCOME_COLOUR else 99)
    names = list(groups)
    traces = [go.Bar(y=names, x=[groups[g].get(o, 0) for g in names], name=o, orientation="h",
                     marker={"color": OUTCOME_COLOUR.get(o, "#777")}) for o in outcomes]
    fig = go.Figure(data=traces, layout={"title": {"text": html.escape(title)}, "barmode": "stack",
                                         "height": 120 + 28 * len(names),
                                         "xaxis": {"title": {"text": "checks"}},
                                         "yaxis": {"autorange": "reversed"}, "margin": {"l": 160}})
    return str(pio.to_html(fig, full_html=False, include_plotlyjs=False, config=CONFIG))


def plotly_js() -> str:
    """plotly.js itself, to inline once in a page."""
    from plotly.offline import get_plotlyjs

    return str(get_plotlyjs())
