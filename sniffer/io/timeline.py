"""A capture's times, watched for running backwards (a problem of the capture, said where it happens).

A capture tool stamps its records in the order it writes them, so a time earlier than the one before it
means the capture's clock was set back (by hand, by a time service's step) or files were joined out of
order; either way the times after it do not follow the ones before. A reader passes each record's time to
``Timeline.check``: a step back of more than ``TOLERANCE_S`` from the record before is reported, at the
record where it happens, and the new times are followed from there (a clock set back once is said once).
Smaller steps are not reported: two taps' delivery order and a clock slewed by a time service move times
back by milliseconds. The bytes keep their own times either way.
"""

from __future__ import annotations

import datetime as _dt
import math
from typing import Final

from .base import Report

TOLERANCE_S: Final = 1.0  # a step back of at most this is no problem


def _stamp(t: float) -> str:
    try:
        return _dt.datetime.fromtimestamp(t, _dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f UTC")
    except (OverflowError, OSError, ValueError):
        return f"{t!r} s"


class Timeline:
    """The time of the last record a capture gave, and the check that the next one does not run backwards.
    A reader's loop may hold ``last`` itself and hand it back (``t + TOLERANCE_S >= last``: no problem)."""

    __slots__ = ("report", "last")

    def __init__(self, report: Report) -> None:
        self.report = report
        self.last = -math.inf

    def check(self, t: float | None, where: str) -> None:
        """Take the next record's time (None: the record has none); report a step back."""
        if t is None:
            return
        if t + TOLERANCE_S < self.last:
            self.report.problem(where, f"time runs backwards: {_stamp(t)} is {self.last - t:.6f} s before "
                                       f"{_stamp(self.last)}, the time of the record before it (the "
                                       f"capture's clock was set back, or files were joined out of order); "
                                       f"the bytes keep their own times")
        self.last = t
