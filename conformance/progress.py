"""What ``xac1 conformance`` shows while it runs and when it ends (pytest's own terminal output is off).

How it works: on a terminal one live line (rich) names the check under way, how many are done and the
elapsed time, refreshed while a check waits for an answer; elsewhere (a log, CI) one line per rule group
as it starts. At the end the report's terminal lines are printed with colour on a terminal, plain
otherwise, never cut (long lines wrap).
"""

from __future__ import annotations

import sys
import time
from typing import Any

from rich.console import Console
from rich.text import Text

STYLES = {"": "", "good": "bold green", "bad": "bold red", "warn": "yellow", "bold": "bold"}


class Progress:
    def __init__(self, console: Console | None = None) -> None:
        # The real stdout: pytest captures sys.stdout while a check runs (xac1 conformance: --capture=sys).
        self.console = console or Console(file=sys.__stdout__, highlight=False, soft_wrap=True)
        self.started = time.monotonic()
        self.total = 0
        self.done = 0
        self.current = "starting"
        self.topic = ""
        self._live: Any = None

    def elapsed(self) -> str:
        return f"{time.monotonic() - self.started:5.1f} s"

    def __rich__(self) -> Text:
        return Text(f"xac1 conformance: {self.elapsed()} [{self.done}/{self.total}] {self.current}",
                    no_wrap=True, overflow="ellipsis")

    def say(self, text: str) -> None:
        """A line that stays (above the live line on a terminal)."""
        self.console.print(Text(text), soft_wrap=True)

    def begin(self, total: int, info: int = 0) -> None:
        """``total`` checks will run, ``info`` of them checks that record information (the verdict counts
        the others: the checks of stated rules), said once so that the two counts never disagree. A check
        that records information may record several observations: the report counts those as records."""
        self.total = total
        if info:
            self.say(f"xac1 conformance: {total} checks to run: {total - info} of stated rules (the verdict "
                     f"counts these) and {info} that record information")
        if self.console.is_terminal:
            from rich.live import Live

            self._live = Live(self, console=self.console, refresh_per_second=4, transient=True)
            self._live.start()

    def check(self, topic: str, name: str) -> None:
        self.current = f"{topic}: {name}"
        if topic != self.topic:
            self.topic = topic
            if self._live is None:
                self.say(f"xac1 conformance: [{self.elapsed()}] {topic} "
                         f"(check {self.done + 1} of {self.total})")

    def finished_one(self) -> None:
        self.done += 1

    def stop(self) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None

    def lines(self, lines: list[tuple[str, str]]) -> None:
        self.stop()
        for line, style in lines:
            self.console.print(Text(line, style=STYLES.get(style, "")), soft_wrap=True)
