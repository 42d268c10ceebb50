"""The HTML session report (``--report FILE`` of ``xac1 decode``, ``xac1 sniff`` and ``xac1 proxy``).

How this works: ``SessionReport.open(path, sources)`` checks, before any work, that plotly (the
``report`` extra) is installed and that ``path`` can be written, else raises ``ReportError`` (a
``ValueError``) with a message saying what to do. Its ``feed(analyzer, chunk)`` passes a chunk through
the analyzer and takes its records (a line at a time, the engine asked after each line: ``decode``), or
``add`` takes every record the analyzer makes once ``judged_by`` named its engine (the live sniffer);
``aggregate.SessionAggregator`` keeps bounded memory; ``write(summary)`` renders the page
(``page.render_page``) and writes it atomically. The verdicts are the records' own, and what the
conversation established (alarm spans, positions, move estimates) is the engine's (docs/protocol.md
"Violation codes"): the report draws them and judges nothing.

Why plotly: it writes offline HTML with its JavaScript inlined, draws zoomable, clickable plots of
tens of thousands of points, and is widely used and maintained. Its Python package is large (about 60
MB installed), hence the optional extra; nothing else in the project imports it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..records import Record
from .aggregate import Limits, SessionAggregator

if TYPE_CHECKING:
    from xac1_proto.chunk import Chunk
    from xac1_proto.conversation import Conversation

    from ..analyzer import Analyzer

EXTRA_HINT = "pip install 'xac1-proto[report]'"


class ReportError(ValueError):
    """The report cannot be made (plotly missing, a path that cannot be written)."""


def require_plotly() -> None:
    """Raise ``ReportError`` naming the extra when plotly is not installed."""
    try:
        import plotly  # noqa: F401
    except ImportError:
        raise ReportError(f"--report needs the optional 'report' extra (plotly): {EXTRA_HINT}") from None


def check_writable(path: str | os.PathLike[str]) -> Path:
    """The file to write for the report's path (through a symbolic link, to its target), once sure it
    can be written as a regular file: never a directory, FIFO or device (``xac1_proto.output_file``)."""
    from xac1_proto.output_file import OutputFileError, check_output

    try:
        return check_output(path, "cannot write the report")
    except OutputFileError as exc:
        raise ReportError(str(exc)) from None


class SessionReport:
    """A report being gathered: ``add`` records, then ``write`` once."""

    def __init__(self, path: Path, aggregator: SessionAggregator) -> None:
        self.path = path
        self.aggregator = aggregator
        self.written = False

    @classmethod
    def open(cls, path: str | os.PathLike[str], sources: list[tuple[str, str]],
             no_answer_timeout: float | None = None, limits: Limits | None = None) -> SessionReport:
        require_plotly()
        target = check_writable(path)
        options: dict[str, Any] = {"sources": list(sources), "limits": limits or Limits()}
        if no_answer_timeout is not None:
            options["no_answer_timeout"] = no_answer_timeout
        return cls(target, SessionAggregator(**options))

    def feed(self, analyzer: Analyzer, chunk: Chunk) -> list[Record]:
        """``chunk`` through ``analyzer``, its records taken (``SessionAggregator.feed``); returns them."""
        return self.aggregator.feed(analyzer, chunk)

    def judged_by(self, engine: Conversation) -> None:
        """The engine whose records ``add`` takes: asked what it established (alarm spans, positions,
        moves)."""
        self.aggregator.engine = engine

    def add(self, record: Record) -> None:
        self.aggregator.add(record)

    def write(self, summary: dict[str, Any] | None = None) -> Path:
        """Render and write the page (once); the analyzer's ``summary`` gives the summary tables."""
        from .page import render_page, write_page

        if not self.written:
            self.aggregator.finish(summary)
            write_page(self.path, render_page(self.aggregator))
            self.written = True
        return self.path


def write_empty(path: str | os.PathLike[str], sources: list[tuple[str, str]]) -> Path:
    """A report for a capture that holds nothing at all (a file of zero bytes): it says so."""
    report = SessionReport.open(path, sources)
    return report.write()


__all__ = ["EXTRA_HINT", "Limits", "ReportError", "SessionAggregator", "SessionReport", "check_writable",
           "require_plotly", "write_empty"]
