"""The conformance HTML report's pictures (issue 17): the per-rule-group summary and the answer turnaround
histogram, drawn with plotly (the ``report`` extra) and inlined. A real simulator run's report is opened
in headless Chromium (no console error, no network request, both figures drawn with the run's groups and
commands); without plotly (its import made to fail in-process) the same report renders unchanged but for
one line naming the extra."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest
from session_report_browser import CHROMIUM, Browser
from test_fleet import MOTION, Sim

import xac1_proto.pages
from conformance import report as creport
from conformance.report import PICTURES_HINT, Report
from conformance.results import Result

FIGURE = 'class="plotly-graph-div"'


def _report(latencies: dict[str, list[float]]) -> Report:
    checks = [Result("a::t1", "crlf", "framing", "Answers end in CR LF", "3.1", False, "PASS"),
              Result("a::t2", "reset", "alarms", "0%C answers 0%C00", "4.2", False, "FAIL", "expected 0%C00"),
              Result("a::t3", "move", "motion", "0MP moves", "5.1", False, "SKIP", "pass --allow-motion")]
    return Report(port="xac1sim://", version="100", date="2026-01-01 00:00:00 UTC", options=[],
                  checks=checks, infos=[], info_errors=[],
                  timing=[(h, len(v), min(v), sorted(v)[len(v) // 2], max(v)) for h, v in latencies.items()],
                  safety=[], safety_problems=[], abort=None, latencies=latencies, timeout=0.5)


SLOW = {"0RV": [0.004, 0.005, 0.006], "0%C": [0.003, 0.004]}


def test_pictures_in_the_html_report_only_when_plotly_is_there(monkeypatch):
    """With plotly: the group summary and (turnaround measurable) the histogram, plotly.js inlined once,
    no install hint. Without plotly: no figure, no plotly.js, one line naming the extra; the headings and
    tables are the same."""
    rep = _report(SLOW)
    page = creport.html_page(rep)
    assert page.count(FIGURE) == 2 and 'id="group-summary"' in page and 'id="turnaround-histogram"' in page
    assert PICTURES_HINT not in page and page.count("<script>") >= 1
    monkeypatch.delitem(sys.modules, "xac1_proto.pages.figures", raising=False)
    monkeypatch.delattr(xac1_proto.pages, "figures", raising=False)  # loaded afresh: plotly is then missing
    monkeypatch.setitem(sys.modules, "plotly", None)  # `import plotly` now raises ImportError
    plain = creport.html_page(rep)
    assert FIGURE not in plain and "plotly" not in plain.lower().replace(PICTURES_HINT, "")
    escaped = PICTURES_HINT.replace("'", "&#39;")
    hint = [line for line in plain.splitlines() if escaped in line]
    assert hint == [f'<p class="dim">Pictures of the rule groups and of the answer turnaround: {escaped}</p>']

    def text(html: str) -> list[str]:  # headings and table rows: what the reader reads
        return re.findall(r"<h[123][^>]*>.*?</h[123]>|<tr>.*?</tr>", html)

    assert text(plain) == text(page) and "DOES NOT CONFORM" in plain and "expected 0%C00" in plain
    # the Markdown report never had pictures
    assert FIGURE not in creport.markdown(rep) and PICTURES_HINT not in creport.markdown(rep)


def test_no_histogram_when_turnaround_means_nothing():
    """An instant (time-scaled) simulator: the turnaround table is left out, so is its histogram."""
    page = creport.html_page(_report({"0RV": [0.0, 0.0001], "0%C": [0.0]}))
    assert page.count(FIGURE) == 1 and 'id="turnaround-histogram"' not in page


@pytest.mark.slow
@pytest.mark.skipif(not shutil.which(CHROMIUM) and not os.environ.get("CI"),
                    reason="chromium is not installed (Debian package chromium)")
def test_simulator_run_report_draws_both_figures_in_chromium(tmp_path):
    """A real run against ``xac1 sim`` whose answers take measurable time: the report holds both figures;
    Chromium loads it with no console error and no network request; the histogram has one trace per
    command the run timed and the deadline at the run's answer timeout; the group figure one bar per
    rule group of the summary table."""
    sim = Sim(tmp_path, "slow", "--time-scale", "0.05", "--turnaround", "60")
    try:
        out = tmp_path / "r.html"
        r = subprocess.run([sys.executable, "-m", "xac1_proto", "conformance", "--port", sim.url, *MOTION,
                            "--timeout", "0.4", "--report", str(out)], cwd=tmp_path, capture_output=True,
                           text=True, timeout=180)
    finally:
        sim.close()
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    html = out.read_text()
    assert html.count(FIGURE) == 2
    table = html.split("<h2>Answer turnaround</h2>", 1)[1].split("</table>", 1)[0]
    commands = re.findall(r"<tr><td>([^<]+)</td><td>\d+</td>", table)
    groups = re.findall(r'<tr><td>([^<]+)</td><td class="(?:PASS|FAIL|SKIP)">',
                        html.split("<h2>Summary by rule group</h2>", 1)[1].split("</table>", 1)[0])
    assert len(commands) > 5 and len(groups) > 5
    chrome = Browser()
    try:
        page = chrome.open(out)
        assert page.problems() == []
        assert page.requests() == []
        drawn = page.evaluate("""(() => {
          const fig = id => document.querySelector("#" + id + " .js-plotly-plot");
          const h = fig("turnaround-histogram"), g = fig("group-summary");
          return {h: h && !!h._fullLayout, g: g && !!g._fullLayout,
                  commands: h.data.map(t => t.name).sort(),
                  deadline: h.layout.shapes.map(s => s.x0),
                  groups: [...new Set(g.data.flatMap(t => t.y))],
                  bars: g.querySelectorAll(".barlayer .point").length};
        })()""")
    finally:
        chrome.close()
    assert drawn["h"] and drawn["g"]
    assert drawn["commands"] == sorted(commands)
    assert drawn["deadline"] == [400]
    assert sorted(drawn["groups"]) == sorted(groups) and drawn["bars"] >= len(groups)
