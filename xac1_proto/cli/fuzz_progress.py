"""``xac1 fuzz``'s live progress bar (rich, on stderr): cases, findings, time left. Off when stderr is
no terminal (a log or a pipe gets the results alone)."""

from __future__ import annotations

import time
from typing import Any


class ProgressBar:
    """A context manager; ``advance(findings)`` after each case."""

    def __init__(self, cases: int | None, seconds: float | None, *, enabled: bool) -> None:
        self.cases = cases
        self.seconds = seconds
        self.enabled = enabled
        self._progress: Any = None
        self._task: Any = None
        self._started = time.monotonic()
        self._done = 0

    def __enter__(self) -> ProgressBar:
        if not self.enabled:
            return self
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

        self._progress = Progress(TextColumn("xac1 fuzz"), BarColumn(), TextColumn("{task.fields[what]}"),
                                  TimeRemainingColumn(), console=Console(stderr=True), transient=True)
        self._progress.start()
        total = self.cases if self.cases is not None else self.seconds
        self._task = self._progress.add_task("fuzz", total=total, what=self._what(0))
        return self

    def _what(self, findings: int) -> str:
        return f"{self._done} cases, {findings} finding(s)"

    def advance(self, findings: int) -> None:
        self._done += 1
        if self._progress is None:
            return
        done = self._done if self.cases is not None else time.monotonic() - self._started
        self._progress.update(self._task, completed=done, what=self._what(findings))

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()
