"""Progress of one device's run, told to the fleet that started it (``conformance.fleet``).

The fleet starts each ``xac1 conformance --port X`` child with this module in ``PYTEST_PLUGINS`` and the
number of a pipe's write end in ``XAC1_FLEET_PROGRESS_FD``; pytest loads it next to the suite's own
plugin, and it writes one JSON object a line to that pipe: ``{"of": N}`` once the checks are collected,
``{"check": NAME, "n": K}`` as each check starts, ``{"state": TEXT}`` when the session ends (restore,
report). It judges nothing and changes nothing in the run; without the variable it does nothing.
"""

from __future__ import annotations

import contextlib
import json
import os

import pytest

ENV = "XAC1_FLEET_PROGRESS_FD"
_started = 0


def _tell(event: dict[str, object]) -> None:
    fd = os.environ.get(ENV)
    if not fd:
        return
    with contextlib.suppress(OSError, ValueError):  # the fleet went away: the run itself goes on
        os.write(int(fd), (json.dumps(event) + "\n").encode())


def check_name(nodeid: str) -> str:
    """``conformance/checks/test_alarms.py::test_alarm_latched[0WP]`` -> ``alarm_latched[0WP]``."""
    name = nodeid.rpartition("::")[2]
    return name[len("test_"):] if name.startswith("test_") else name


def pytest_collection_finish(session: pytest.Session) -> None:
    """The checks collected: the count of those started begins again."""
    global _started
    _started = 0
    _tell({"of": len(session.items)})


def pytest_runtest_logstart(nodeid: str, location: object) -> None:
    global _started
    _started += 1
    _tell({"check": check_name(nodeid), "n": _started})


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    _tell({"state": "restoring the device, writing the report"})
