"""Plotly figures of a session: timeline, activity, answer latency, axis position (the fragments other
reports embed are ``xac1_proto.pages.figures``).

How this works. Each function takes the bounded aggregates of ``SessionAggregator`` and returns a
``plotly.graph_objects.Figure`` (validated by plotly as it is built). The page embeds the figures as
JSON and draws them with the one inlined copy of plotly.js; points carry in ``customdata`` the index of
the record they stand for, which the page shows when a point is clicked. Times are unix seconds,
drawn on a date axis (UTC); captures without time are drawn against the record number. Importing this
module imports plotly: only the report needs it (the ``report`` extra).
"""

from __future__ import annotations

from typing import Any

import plotly.graph_objects as go
import plotly.io as pio

from xac1_proto import spec

from .aggregate import LogHistogram, SessionAggregator

LANE = {"host": 1.0, "device": 0.0}
MARK_STEP = 0.16  # vertical offset between the violation marks of one record
LANE_COLOUR = {"host": "#1f77b4", "device": "#2ca02c"}
# one colour per violation code, fixed so a code looks the same in every report
_PALETTE = ("#d62728", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf", "#7f0000",
            "#ff1493", "#b8860b", "#4b0082", "#006400", "#dc143c", "#00008b", "#ff4500", "#2f4f4f",
            "#8b008b", "#556b2f", "#c71585", "#1e90ff", "#a0522d", "#708090")
CODE_COLOUR: dict[str, str] = {code: _PALETTE[i % len(_PALETTE)]
                               for i, code in enumerate(spec.VIOLATION_TABLE)}
# and one marker shape per code, counted apart among notices (all of one colour) and errors, so that
# close marks of like colours still tell apart
_SYMBOLS = ("diamond", "square", "triangle-up", "star", "hexagon", "triangle-down", "pentagon", "cross",
            "star-diamond", "hourglass", "bowtie")
_NOTICES = [code for code, v in spec.VIOLATION_TABLE.items() if v.severity == spec.NOTICE]
_ERRORS = [code for code in spec.VIOLATION_TABLE if code not in _NOTICES]
CODE_SYMBOL: dict[str, str] = {code: _SYMBOLS[i % len(_SYMBOLS)]
                               for codes in (_NOTICES, _ERRORS) for i, code in enumerate(codes)}
NOTICE_COLOUR = "#d4a017"
ALARM_STRIP_Y = 0.5  # alarm answers: the middle of the strip above the position plot (its own axis)


def code_colour(code: str) -> str:
    vspec = spec.VIOLATION_TABLE.get(code)  # type: ignore[call-overload]
    if vspec is not None and vspec.severity == spec.NOTICE:
        return NOTICE_COLOUR
    return CODE_COLOUR.get(code, "#d62728")


def _xs(agg: SessionAggregator, xs: list[float]) -> list[float]:
    """Axis values: milliseconds for the date axis, record numbers as they are."""
    return [x * 1000.0 for x in xs] if agg.timed else xs


def _x_axis(agg: SessionAggregator, title: str = "") -> dict[str, Any]:
    if agg.timed:
        axis: dict[str, Any] = {"type": "date", "title": {"text": title or "time (UTC)"}}
        if agg.t_first is not None and agg.t_last is not None:  # every time plot spans the capture
            pad = max(0.02 * (agg.t_last - agg.t_first), 0.05)
            axis["range"] = [(agg.t_first - pad) * 1000.0, (agg.t_last + pad) * 1000.0]
        return axis
    return {"type": "linear", "title": {"text": title or "record number (the capture has no time)"}}


def _layout(agg: SessionAggregator, title: str, height: int, **more: Any) -> dict[str, Any]:
    layout: dict[str, Any] = {"title": {"text": title}, "height": height, "dragmode": "zoom",
                              "margin": {"l": 70, "r": 20, "t": 50, "b": 50}, "hovermode": "closest",
                              "xaxis": _x_axis(agg), "legend": {"orientation": "h", "y": -0.25}}
    layout.update(more)
    return layout


def timeline(agg: SessionAggregator) -> go.Figure:
    """Host and device lanes, each exchange a line from command to answer, violations as coloured
    marks (on the lane of the side at fault) with their code; clicking a point shows its record."""
    traces = _exchange_lines(agg) + _record_points(agg) + _violation_marks(agg)
    layout = _layout(agg, "Timeline: host and device lanes (point at a mark for its code, click it for its "
                          "bytes)", 460,
                     yaxis={"tickvals": [0, 1], "ticktext": ["device", "host"], "range": [-1.2, 2.2],
                            "fixedrange": True, "zeroline": False})
    return go.Figure(data=traces, layout=layout)


def _exchange_lines(agg: SessionAggregator) -> list[go.Scatter]:
    """The timeline's lines from lane to lane: each exchange from its command to its answer (grey), each
    unanswered command to its deadline (red, dotted; a trace only when there is one)."""
    scale = 1000.0 if agg.timed else 1.0
    ex_x: list[float | None] = []
    ex_y: list[float | None] = []
    for ex in agg.exchanges:
        ex_x += [ex["from"], ex["to"], None]
        ex_y += [LANE["host"], LANE["device"], None]
    traces = [go.Scatter(x=[None if v is None else v * scale for v in ex_x], y=ex_y, mode="lines",
                         name=f"exchange ({len(agg.exchanges)})", hoverinfo="skip",
                         line={"color": "#999", "width": 1}, meta="exchanges")]
    un_x: list[float | None] = []
    un_y: list[float | None] = []
    for un in agg.unanswered:
        un_x += [un["from"] * scale, un["to"] * scale, None]
        un_y += [LANE["host"], LANE["device"], None]
    if un_x:
        traces.append(go.Scatter(x=un_x, y=un_y, mode="lines", name=f"unanswered ({len(agg.unanswered)})",
                                 hoverinfo="skip", line={"color": "#d62728", "width": 1, "dash": "dot"},
                                 meta="unanswered"))
    return traces


def _record_points(agg: SessionAggregator) -> list[go.Scatter]:
    """The timeline's records on their side's lane: frames as circles, junk runs as crosses, a trace
    per side and kind that has any; a point's data is its record's index (a click shows it)."""
    traces = []
    for direction in ("host", "device"):
        for kind, symbol in (("frame", "circle"), ("junk", "x")):
            rows = [(i, r) for i, r in enumerate(agg.records) if r["dir"] == direction and r["type"] == kind]
            if not rows:
                continue
            traces.append(go.Scatter(
                x=_xs(agg, [r["x"] for _, r in rows]), y=[LANE[direction]] * len(rows), mode="markers",
                name=f"{direction} {kind}s ({len(rows)})", customdata=[i for i, _ in rows],
                hovertext=[f"#{r['i']} {r.get('bytes', '')}" for _, r in rows], hoverinfo="text+x",
                marker={"symbol": symbol, "size": 7, "color": LANE_COLOUR[direction]},
                meta=f"{direction}-{kind}"))
    return traces


def _violation_marks(agg: SessionAggregator) -> list[go.Scatter]:
    """The timeline's violations, a trace per code in the spec's order: each mark beside the lane of
    the side at fault (outward, stacked when one record has several)."""
    stacked: dict[int, int] = {}
    by_code: dict[str, list[dict[str, Any]]] = {}
    for mark in agg.marks:
        by_code.setdefault(mark["code"], []).append(mark)
    traces = []
    for code in sorted(by_code, key=lambda c: list(spec.VIOLATION_TABLE).index(c)
                       if c in spec.VIOLATION_TABLE else 99):
        marks = by_code[code]
        ys = []
        for mark in marks:
            k = stacked.get(mark["record"], 0)
            stacked[mark["record"]] = k + 1
            away = (k + 1) * MARK_STEP
            ys.append(LANE[mark["side"]] + (away if mark["side"] == "host" else -away))
        meaning = _meaning(code)
        traces.append(go.Scatter(  # the code is the legend's and the hover's: drawn text overlaps
            x=_xs(agg, [m["x"] for m in marks]), y=ys, mode="markers", name=f"{code} ({len(marks)})",
            text=[code] * len(marks), customdata=[m["record"] for m in marks],
            hovertext=[f"{code} ({m['side']}){meaning}" for m in marks], hoverinfo="text+x",
            marker={"symbol": CODE_SYMBOL.get(code, "diamond"), "size": 11, "color": code_colour(code)},
            meta="violation"))
    return traces


def _meaning(code: str) -> str:
    vspec = spec.VIOLATION_TABLE.get(code)  # type: ignore[call-overload]
    return f": {vspec.meaning}" if vspec is not None else ""


def activity(agg: SessionAggregator) -> go.Figure:
    """The whole capture per time bin: frames by side and violations by code."""
    bins = agg.bins
    traces = []
    for key in bins.keys():  # noqa: SIM118 - TimeBins.keys(), not a dict
        xs, counts, _, _ = bins.series(key)
        kind, _, what = key.partition(":")
        if kind == "violation":
            traces.append(go.Bar(x=_xs(agg, xs), y=counts, name=what, marker={"color": code_colour(what)},
                                 yaxis="y2", meta="violation"))
        else:
            label = "junk runs" if what == "junk" else "frames"
            traces.append(go.Scatter(x=_xs(agg, xs), y=counts, name=f"{kind} {label}", mode="lines",
                                     line={"color": LANE_COLOUR.get(kind, "#777"), "shape": "hv"}))
    unit = f"{bins.width:g} s" if agg.timed else f"{bins.width:g} records"
    layout = _layout(agg, f"Activity over the whole capture (per {unit})", 380, barmode="stack",
                     yaxis={"title": {"text": "frames per bin"}, "rangemode": "tozero"},
                     yaxis2={"title": {"text": "violations per bin (bars)"}, "overlaying": "y",
                             "side": "right", "rangemode": "tozero", "showgrid": False})
    return go.Figure(data=traces, layout=layout)


def latency_histogram(agg: SessionAggregator) -> go.Figure:
    """Answer latency per command (ms, log axis), with the no-answer deadline drawn."""
    traces = []
    for header in sorted(agg.latency_hist):
        hist = agg.latency_hist[header]
        xs: list[float] = []
        ys: list[int] = []
        for value, n in hist.items():  # a step outline per bucket: bars do not draw well on a log axis
            right = value + LogHistogram.step(value)
            xs += [value, value, right, right]
            ys += [0, n, n, 0]
        traces.append(go.Scatter(x=xs, y=ys, mode="lines", fill="tozeroy", name=f"{header} ({hist.n})",
                                 opacity=0.75))
    return _with_deadline(agg, go.Figure(data=traces, layout={
        "title": {"text": "Answer latency per command"}, "height": 360, "hovermode": "closest",
        "margin": {"l": 70, "r": 20, "t": 50, "b": 50},
        "xaxis": {"type": "log", "title": {"text": "latency, ms (command's last byte to the answer)"}},
        "yaxis": {"title": {"text": "answers"}}}), vertical=True)


def latency_over_time(agg: SessionAggregator) -> go.Figure:
    """Latency of each answer over time (or, for long captures, per-bin mean and max)."""
    traces = []
    points = agg.latency_points
    if points.thinned:
        for header in agg.latency_bins.keys():  # noqa: SIM118 - not a dict
            xs, _, means, tops = agg.latency_bins.series(header)
            traces.append(go.Scatter(x=_xs(agg, xs), y=means, mode="lines", name=f"{header} mean"))
            traces.append(go.Scatter(x=_xs(agg, xs), y=tops, mode="markers", name=f"{header} max",
                                     marker={"size": 4}))
    else:
        by_header: dict[str, list[tuple[float, float, int | None]]] = {}
        for x, ms, header, kept in points.items:
            by_header.setdefault(header, []).append((x, ms, kept))
        for header in sorted(by_header):
            rows = by_header[header]
            traces.append(go.Scatter(x=_xs(agg, [r[0] for r in rows]), y=[r[1] for r in rows],
                                     mode="markers", name=header, customdata=[r[2] for r in rows],
                                     marker={"size": 6}))
    layout = _layout(agg, "Answer latency over time", 360, yaxis={"type": "log", "title": {"text": "ms"}})
    return _with_deadline(agg, go.Figure(data=traces, layout=layout), vertical=False)


def _with_deadline(agg: SessionAggregator, fig: go.Figure, vertical: bool) -> go.Figure:
    deadline = agg.no_answer_timeout * 1000.0
    label = f"no-answer deadline {deadline:g} ms (moves: longer)"
    if vertical:
        fig.add_vline(x=deadline, line={"color": "#b00020", "dash": "dash"}, annotation_text=label)
    else:
        fig.add_hline(y=deadline, line={"color": "#b00020", "dash": "dash"}, annotation_text=label)
    return fig


def position(agg: SessionAggregator) -> go.Figure:
    """Axis position from the answers, moves with their estimated duration, homing; alarm answers in a
    strip above (an alarm says no position). Only positions an answer gave are drawn: none where it is
    unknown (``None``), whatever the aggregate's source."""
    traces: list[go.Scatter] = []
    pts = [p for p in agg.positions.items if p[1] is not None]
    traces.append(go.Scatter(x=_xs(agg, [p[0] for p in pts]), y=[p[1] for p in pts], mode="markers",
                             name="position answered (0RC/0MP/0MV)", customdata=[p[3] for p in pts],
                             hovertext=[f"{p[2]} Pos {p[1]:#08x} ({p[1]})" for p in pts], hoverinfo="text+x",
                             marker={"size": 7, "color": "#1f77b4"}))
    mx: list[float | None] = []
    my: list[float | None] = []
    for x_cmd, x_est, x_ans, start, end, _header in agg.moves.items:
        if start is None or end is None:
            continue
        mx += [x_cmd, x_est, x_ans, None]
        my += [start, end, end, None]
    traces.append(go.Scatter(x=[None if v is None else v * (1000.0 if agg.timed else 1.0) for v in mx], y=my,
                             mode="lines", name="move (estimated duration)", hoverinfo="skip",
                             line={"color": "#1f77b4", "dash": "dot"}))
    homing = agg.homings.items
    traces.append(go.Scatter(x=_xs(agg, homing), y=[0] * len(homing), mode="markers", name="homing",
                             marker={"symbol": "triangle-up", "size": 12, "color": "#2ca02c"}))
    by_code: dict[int, list[tuple[float, int, int | None]]] = {}
    for alarm in agg.alarm_marks.items:
        by_code.setdefault(alarm[1], []).append(alarm)
    for code in sorted(by_code):
        alarms = by_code[code]
        traces.append(go.Scatter(x=_xs(agg, [a[0] for a in alarms]), y=[ALARM_STRIP_Y] * len(alarms),
                                 yaxis="y2", mode="markers", name=f"alarm {code:02X} ({len(alarms)})",
                                 hovertext=[f"alarm {code:02X}: {spec.alarm_meaning(code)}"] * len(alarms),
                                 hoverinfo="text+x", customdata=[a[2] for a in alarms], meta="alarm",
                                 marker={"symbol": "x", "size": 11, "color": "#d62728"}))
    layout = _layout(agg, "Axis position as the answers tell it (alarm answers in the strip above)", 380,
                     yaxis={"title": {"text": "Pos (pulses)"}, "rangemode": "tozero", "domain": [0, 0.86]},
                     yaxis2={"domain": [0.9, 1], "range": [0, 1], "fixedrange": True, "showgrid": False,
                             "zeroline": False, "tickvals": [ALARM_STRIP_Y], "ticktext": ["alarms"]})
    return go.Figure(data=traces, layout=layout)


def to_json(fig: go.Figure) -> str:
    return str(pio.to_json(fig, validate=False))
