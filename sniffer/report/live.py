"""The live sniffer's session with a report: every record also goes to the report, which is written
when the session closes (the run's end, Ctrl-C, SIGTERM, a tap gone for good)."""

from __future__ import annotations

import sys
from typing import Any

from xac1_proto.recording import RecordingWriter

from ..analyzer import Analyzer
from ..live import Session
from ..view import View
from . import SessionReport


class ReportingSession(Session):
    """``live.Session`` that feeds a ``SessionReport`` and writes it on ``close``."""

    def __init__(self, analyzer: Analyzer, view: View, recorder: RecordingWriter | None,
                 report: SessionReport, **shell: Any) -> None:
        """``shell``: ``Session``'s ``output``, ``err`` and ``program``."""
        super().__init__(analyzer, view, recorder, on_record=report.add, **shell)
        report.judged_by(analyzer.conversation)  # records come a chunk at a time: asked after each
        self.report = report

    def close(self, now: float | None, summary: bool = True) -> None:
        if self.closed:
            return
        try:
            super().close(now, summary)
        finally:
            if summary:  # the run started: there is a session to show
                try:
                    path = self.report.write(self.analyzer.summary())
                    print(f"report written to {path}", file=sys.stderr)
                except (OSError, ValueError) as exc:  # ValueError: no longer a regular file
                    print(f"error: cannot write the report {self.report.path}: "
                          f"{getattr(exc, 'strerror', None) or exc}",
                          file=sys.stderr)
