"""What ``xac1 fuzz`` writes: a capture per finding (``--save DIR``), the report (``--report``: HTML or
Markdown by suffix) and JUnit XML (``--junit``).

A capture is the project's recording format (``xac1_proto.recording``, as ``xac1 sim --log`` writes it):
the chunks of the re-run that confirmed the shrunk finding (or of the case that found it), times made
unix seconds, so that ``xac1 replay FILE --port URL`` plays its host lines again. The pages render
through the project's one Jinja2 environment (``xac1_proto.pages``: ``fuzz.html.j2``, ``fuzz.md.j2``)
and are written whole or not at all (``xac1_proto.output_file``); JUnit has one test case a kind of
finding (silence, answer, state), failed with each finding of that kind.
"""

from __future__ import annotations

import datetime as _dt
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from xac1_proto.chunk import Chunk
from xac1_proto.fuzz.judge import KINDS
from xac1_proto.fuzz.results import Reported, RunSummary, wire
from xac1_proto.output_file import write_output
from xac1_proto.recording import RecordingWriter

KIND_MEANING = {
    "silence": "the unit stopped answering (no answer to the liveness probe within the answer window)",
    "answer": "the unit answered a well-formed probe otherwise than at the start",
    "state": "the unit changed its stored points or OUT ports without being told to",
}


def save_capture(folder: str, number: int, reported: Reported, chunks: list[Chunk], clock_offset: float,
                 source: str) -> str:
    """Write the finding's capture into ``folder``; its path."""
    path = Path(folder) / f"finding-{number}-{reported.finding.kind}.jsonl"
    t0 = chunks[0].t if chunks and chunks[0].t is not None else 0.0
    with RecordingWriter(path, source=source, started=t0 + clock_offset) as rec:
        rec.note(f"xac1 fuzz finding {number}: {reported.finding.kind}: {reported.finding.detail}",
                 t0 + clock_offset)
        for c in chunks:
            rec.write(Chunk(None if c.t is None else c.t + clock_offset, c.dir, c.data))
    return os.fspath(path)


def context(summary: RunSummary) -> dict[str, Any]:
    rows = [{"n": k + 1, "kind": r.finding.kind, "meaning": KIND_MEANING[r.finding.kind],
             "input": [wire(x) for x in r.finding.lines], "detail": r.finding.detail,
             "codes": list(r.finding.codes), "case": r.case, "shrunk": r.shrunk, "why": r.why,
             "found_lines": len(r.found), "tries": r.tries, "capture": r.capture}
            for k, r in enumerate(summary.findings)]
    return {"title": "XA-C1 fuzz report", "s": summary.as_dict(), "rows": rows,
            "generated": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")}


def write_report(path: str, summary: RunSummary) -> str:
    """The page (Markdown when ``path`` ends in .md, else HTML); the path written (OSError if not)."""
    from xac1_proto.pages import render

    name = "fuzz.md.j2" if path.lower().endswith((".md", ".markdown")) else "fuzz.html.j2"
    write_output(path, render(name, **context(summary)))
    return path


def junit_xml(summary: RunSummary) -> bytes:
    """One test case a kind of finding, failed with every finding of that kind."""
    suite = ET.Element("testsuite", name="xac1 fuzz", tests=str(len(KINDS)),
                       failures=str(sum(1 for k in KINDS if summary.by_kind[k])),
                       time=f"{summary.seconds:.3f}")
    props = ET.SubElement(suite, "properties")
    for key, value in (("port", summary.port), ("seed", str(summary.seed)), ("cases", str(summary.cases))):
        ET.SubElement(props, "property", name=key, value=value)
    for kind in KINDS:
        case = ET.SubElement(suite, "testcase", classname="xac1.fuzz", name=f"no {kind} finding")
        mine = [r for r in summary.findings if r.finding.kind == kind]
        if mine:
            text = "\n\n".join(f"input: {' '.join(wire(x) for x in r.finding.lines)}\n{r.finding.detail}\n"
                               f"codes: {', '.join(r.finding.codes) or 'none'}"
                               + (f"\ncapture: {r.capture}" if r.capture else "") for r in mine)
            fail = ET.SubElement(case, "failure",
                                 message=f"{len(mine)} {kind} finding(s): {KIND_MEANING[kind]}")
            fail.text = text
    return ET.tostring(suite, encoding="utf-8", xml_declaration=True)


def write_junit(path: str, summary: RunSummary) -> str:
    write_output(path, junit_xml(summary))
    return path
