"""One check's outcome as data: ``Result``, made from pytest's report by ``result_from``.

How it works: the rule is the first paragraph of the check's docstring (``{id}`` replaced by the
check's parameter), the docs/protocol.md section is the quoted section name or silent item it cites,
the topic is the check's module (``test_framing`` -> ``framing``). A check a person must do by hand
raises ``ManualStep``: it is neither run nor missing, the report lists what to do and what to see.
This module imports nothing from the plugin or the report, so both can use it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

from xac1_proto.dut.evidence import Probe, RuleBroken

PASS, FAIL, ERROR, SKIP, MANUAL = "PASS", "FAIL", "ERROR", "SKIP", "MANUAL"
MANUAL_TAG = "manual step: "
_SECTION = re.compile(r'docs/protocol\.md[\s,]+((?:silent item \d+)|(?:"[^"]+"))')


class ManualStep(Exception):
    """A check only a person can do on this device (e.g. press the emergency stop): what to do, what to
    see. Not a skip: the report lists it as a manual step and the verdict does not wait for it."""

    def __init__(self, do: str, see: str) -> None:
        super().__init__(f"{do}; expect: {see}")
        self.do, self.see = do, see


@dataclass
class Result:
    nodeid: str
    check: str
    topic: str
    rule: str
    section: str
    info: bool
    verdict: str
    message: str = ""
    probes: list[Probe] = field(default_factory=list)


def section_of(doc: str) -> str:
    """The docs/protocol.md section a check's docstring cites ('' when none)."""
    m = _SECTION.search(" ".join((doc or "").split()))
    return m.group(1).strip('"') if m else ""


def _rule(item: Any) -> str:
    doc = (getattr(getattr(item, "function", None), "__doc__", None) or "").strip()
    text = " ".join(doc.split("\n\n")[0].split())
    callspec = getattr(item, "callspec", None)
    if callspec is not None:
        text = text.replace("{id}", callspec.id)
    return text or item.name


def _skip_text(report: Any) -> str:
    lr = report.longrepr
    return str(lr[2] if isinstance(lr, tuple) else lr).removeprefix("Skipped: ")


def result_from(item: Any, report: Any, call: Any, dut: Any) -> Result:
    probes: list[Probe] = []
    message = ""
    exc = call.excinfo.value if call.excinfo is not None else None
    if report.skipped:
        message = _skip_text(report)
        verdict = SKIP
        if message.startswith(MANUAL_TAG):
            verdict, message = MANUAL, message.removeprefix(MANUAL_TAG)
    elif report.passed:
        verdict = PASS
    elif isinstance(exc, AssertionError) and report.when == "call":
        verdict = FAIL
        message = str(exc).split("\nassert ")[0].strip()
        if isinstance(exc, RuleBroken):
            probes = list(exc.probes)
    else:
        verdict = ERROR
        message = f"{type(exc).__name__}: {exc}" if exc is not None else str(report.longrepr)[-400:]
    if dut is not None:
        probes += [p for p in dut.probes_for(item.nodeid) if p not in probes]
    module = getattr(item, "module", None)
    topic = (module.__name__.rsplit(".", 1)[-1] if module else "").removeprefix("test_")
    doc = getattr(getattr(item, "function", None), "__doc__", "") or ""
    return Result(item.nodeid, item.name.removeprefix("test_"), topic, _rule(item), section_of(doc),
                  item.get_closest_marker("xac1_info") is not None, verdict, message, probes)
