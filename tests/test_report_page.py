"""The HTML session report's page and its live session, in-process (``sniffer.report.page``,
``sniffer.report.live``): the gallery session decoded, drawn into one offline page that shows the
records' own verdicts; a live session writes its report when it closes."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from sniffer.analyzer import Analyzer
from sniffer.io.registry import Capture
from sniffer.report import SessionReport
from sniffer.report.aggregate import SessionAggregator
from sniffer.report.live import ReportingSession
from sniffer.report.page import render_page
from sniffer.view import make_view

pytest.importorskip("plotly")  # the report extra; tests/test_session_report.py covers its absence

SOCAT = Path(__file__).resolve().parent.parent / "captures" / "socat-xv.log"


def _gallery_records() -> tuple[list, dict]:
    analyzer = Analyzer()
    records = []
    with Capture([str(SOCAT)], "socat") as capture:
        for chunk in capture:
            records += analyzer.feed(chunk)
    return records + analyzer.close(), analyzer.summary()


def test_page_draws_the_records_verdicts_offline():
    """Every violation code of the gallery session is on the page, and the page requests nothing: a
    Content-Security-Policy forbids it and no script or style comes from elsewhere."""
    records, summary = _gallery_records()
    agg = SessionAggregator(sources=[(SOCAT.name, "socat")])
    for r in records:
        agg.add(r)
    agg.finish(summary)
    page = render_page(agg)
    for code in summary["violations"]:
        assert code in page, code
    assert "Content-Security-Policy" in page and "<script src=" not in page


def test_live_session_writes_its_report_when_it_closes(tmp_path, capsys):
    """A live session with ``--report`` feeds every record to the report and writes it on close (a
    signal, the end of the run), naming the file on stderr."""
    target = tmp_path / "live.html"
    report = SessionReport.open(target, [("host tap", "tap"), ("device tap", "tap")])
    out = io.StringIO()
    session = ReportingSession(Analyzer(), make_view("jsonl", out), None, report)
    with Capture([str(SOCAT)], "socat") as capture:
        for chunk in capture:
            session.chunk(chunk)
    assert not target.exists()
    session.close(None)
    page = target.read_text(encoding="utf-8")
    assert "letter-o" in page and report.written
    frames = session.analyzer.summary()["frames"]
    assert out.getvalue().count('"type":"frame"') == frames["host"] + frames["device"] > 0
    assert f"report written to {target}" in capsys.readouterr().err
