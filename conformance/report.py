"""Verdicts as data and the three ways to show them: terminal table, Markdown, HTML.

``result_from`` turns one check's pytest outcome into a ``Result`` (rule from the docstring, verdict,
message, the probes as evidence); ``build`` gathers a whole run into a ``Report``; the writers only
format it. The report is written for someone who has never seen pytest: it says what was tested, on
what, the overall verdict, each rule with the bytes that prove it, and what the device did where the
protocol leaves the choice open.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .evidence import Probe, RuleBroken, wire

PASS, FAIL, ERROR, SKIP = "PASS", "FAIL", "ERROR", "SKIP"
EVIDENCE_LIMIT = 12  # probes listed per check in the report file


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


def _rule(item: Any) -> str:
    doc = (getattr(getattr(item, "function", None), "__doc__", None) or "").strip()
    first = doc.split("\n\n")[0]
    text = " ".join(first.split())
    callspec = getattr(item, "callspec", None)
    if callspec is not None:
        text = text.replace("{id}", callspec.id)
    return text or item.name


def result_from(item: Any, report: Any, call: Any, dut: Any) -> Result:
    from .plugin import section_of

    probes: list[Probe] = []
    message = ""
    exc = call.excinfo.value if call.excinfo is not None else None
    if report.skipped:
        verdict = SKIP
        lr = report.longrepr
        message = str(lr[2] if isinstance(lr, tuple) else lr).removeprefix("Skipped: ")
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


@dataclass
class Report:
    port: str
    version: str
    date: str
    options: list[tuple[str, str]]
    checks: list[Result]
    infos: list[Any]  # dut.Info
    info_errors: list[Result]
    timing: list[tuple[str, int, float, float, float]]
    safety: list[str]
    safety_problems: list[str]
    abort: str | None
    safety_warnings: list[str] = field(default_factory=list)
    no_answer: bool = False  # the device never answered: nothing could be judged
    not_run: int = 0  # checks collected but never run (the run stopped early)
    info_skipped: list[Result] = field(default_factory=list)
    stopped: bool = False  # the device answered, then stopped answering: the run did not complete
    safety_unverified: list[str] = field(default_factory=list)  # the restore could not be done or checked
    not_run_checks: list[tuple[str, str]] = field(default_factory=list)  # (check, interrupted or not run)

    @property
    def all_skipped(self) -> list[Result]:
        """Skipped checks of stated rules, then skipped information records."""
        return self.skipped + self.info_skipped

    @property
    def failed(self) -> list[Result]:
        return [r for r in self.checks if r.verdict in (FAIL, ERROR)]

    @property
    def skipped(self) -> list[Result]:
        return [r for r in self.checks if r.verdict == SKIP]

    @property
    def accepted(self) -> bool:
        passed = [r for r in self.checks if r.verdict == PASS]
        return (bool(passed) and not self.failed and not self.abort and not self.safety_problems
                and not self.safety_unverified)

    @property
    def verdict_line(self) -> str:
        n = {v: sum(r.verdict == v for r in self.checks) for v in (PASS, FAIL, ERROR, SKIP)}
        if self.no_answer and not self.failed:
            return (f"NO ANSWER FROM THE DEVICE: nothing could be checked ({n[PASS]} passed, "
                    f"{self.not_run} not run)")
        head = "CONFORMS" if self.accepted else "DOES NOT CONFORM"
        if not self.failed and (self.abort or self.safety_problems or self.safety_unverified):
            head = "INCOMPLETE" if n[PASS] else "NOT TESTED"
        if self.stopped:
            head = ("DOES NOT CONFORM, then THE DEVICE STOPPED ANSWERING" if self.failed
                    else "THE DEVICE STOPPED ANSWERING: the run did not complete")
        elif self.safety_unverified:
            head += ", and THE DEVICE STOPPED ANSWERING during the restore"
        parts = [f"{n[PASS]} passed", f"{n[FAIL]} failed"]
        if n[ERROR]:
            parts.append(f"{n[ERROR]} broke down (see the details)")
        parts.append(f"{n[SKIP]} skipped")
        if self.not_run:
            parts.append(f"{self.not_run} not run (the run stopped early)")
        return f"{head}: {', '.join(parts)} (of {len(self.checks) + self.not_run} checks of stated rules)"


def build(run: Any) -> Report:
    """Gather a finished (or interrupted) run into a ``Report``."""
    from xac1_proto import __version__

    s, dut = run.settings, run.dut
    options = [
        ("port", s.port + ("  (the built-in simulator)" if s.simulator else "")),
        ("motion", "allowed" if s.motion else "not allowed (motion checks skipped)"),
        ("safe range", s.describe_range()),
        ("fresh device", "yes (power-on checks run first)" if s.fresh else "no (power-on checks skipped)"),
        ("random sequences", f"{s.examples} (seed {s.seed if s.seed is not None else 'derandomized'})"),
        ("points the suite may write", _scratch_text(run)),
        ("kit", f"xac1-proto {__version__}"),
    ]
    checks = [r for r in run.results if not r.info]
    info_errors = [r for r in run.results if r.info and r.verdict in (FAIL, ERROR)]
    info_skipped = [r for r in run.results if r.info and r.verdict == SKIP]
    infos_total = getattr(run, "total_info", 0)
    run_checks = getattr(run, "total", 0) - infos_total
    safety: list[str] = []
    problems: list[str] = []
    if run.snapshot is not None:
        snap = run.snapshot
        safety.append(f"Before the first write the suite read all {len(snap.points)} points, the OUT ports "
                      f"({snap.outputs}) and the position ({snap.position_seen}).")
    elif dut is None:
        safety.append("The device was not opened: nothing was sent to it.")
    else:
        safety.append("The run stopped before the safety snapshot: nothing was written to the device.")
    rr = run.restore_report
    warnings: list[str] = []
    unverified: list[str] = []
    if rr is not None:
        safety += rr.lines
        problems += rr.problems
        warnings += rr.warnings
        unverified += getattr(rr, "unverified", [])
    elif run.snapshot is not None:
        problems.append("the device was not restored (the run ended before the restore step)")
    judged = {r.nodeid for r in run.results}
    interrupted = getattr(run, "interrupted", [])
    cut = "interrupted: the run stopped during this check"
    not_run_checks = [(name + (" (information)" if info else ""), cut if nodeid in interrupted else "not run")
                      for nodeid, name, info in getattr(run, "collected", []) if nodeid not in judged]
    return Report(
        port=s.port, version=(dut.version if dut is not None and dut.version else "unknown"),
        date=run.started.strftime("%Y-%m-%d %H:%M:%S %Z"), options=options, checks=checks,
        infos=list(dut.infos) if dut is not None else [], info_errors=info_errors,
        timing=dut.timing_table() if dut is not None else [], safety=safety, safety_problems=problems,
        abort=run.abort, safety_warnings=warnings, no_answer=getattr(run, "no_answer", False),
        not_run=max(run_checks - len(checks), 0), info_skipped=info_skipped,
        stopped=getattr(run, "stopped", False), safety_unverified=unverified, not_run_checks=not_run_checks)


def _scratch_text(run: Any) -> str:
    s, snap = run.settings, run.snapshot
    named = ", ".join(f"{n:X}" for n in s.scratch_points)
    head = f"named with {s.flag('scratch-points')}: {named}; " if named else ""
    if s.simulator:
        return head + "any point (the built-in simulator)"
    if snap is None:
        return head + "the points that held data (not read: the run stopped first)"
    held = ", ".join(f"{n:X}" for n in sorted(snap.points) if snap.points[n].restorable) or "none"
    return head + f"the points that held data ({held}); never-written points are left alone"


# ---- terminal ----

def _cut(text: str, width: int) -> str:
    return text if len(text) <= width else text[: max(width - 1, 0)] + "~"


def _evidence_short(r: Result) -> str:
    if not r.probes:
        return "-" if r.verdict != SKIP else r.message
    more = f" (+{len(r.probes) - 1} more)" if len(r.probes) > 1 else ""
    return r.probes[0].show() + more


def terminal_lines(rep: Report, width: int = 110) -> list[tuple[str, dict[str, bool]]]:
    """The summary table and what follows it, as (line, markup) pairs for pytest's terminal writer."""
    colour = {PASS: {"green": True}, FAIL: {"red": True, "bold": True}, ERROR: {"red": True},
              SKIP: {"yellow": True}}
    w_check = min(40, max((len(r.check) for r in rep.checks), default=10))
    w_rule = max(30, (width - w_check - 9) * 2 // 5)
    w_ev = max(20, width - w_check - w_rule - 9)
    out: list[tuple[str, dict[str, bool]]] = [(f"device {rep.version} on {rep.port}  |  {rep.date}", {})]
    ran = [r for r in rep.checks if r.verdict != SKIP]
    if ran or not rep.abort:
        out.append((f"{'check':<{w_check}} {'verdict':<6} {'rule':<{w_rule}} evidence (sent -> received)",
                    {"bold": True}))
    for r in rep.checks if ran or not rep.abort else []:
        line = (f"{_cut(r.check, w_check):<{w_check}} {r.verdict:<6} {_cut(r.rule, w_rule):<{w_rule}} "
                f"{_cut(_evidence_short(r), w_ev)}")
        out.append((line, colour[r.verdict]))
    for r in rep.failed:
        out.append(("", {}))
        out.append((f"{r.verdict} {r.check}: {r.rule}", colour[r.verdict]))
        out.append((f"  {r.message}", {}))
        for p in r.probes[:6]:
            out.append((f"    {p.show()}", {}))
    reasons: dict[str, list[str]] = {}
    for r in rep.all_skipped:
        reasons.setdefault(r.message, []).append(r.check + (" (information)" if r.info else ""))
    if reasons:
        out.append(("", {}))
        out.append(("skipped checks (never a failure; to run them):", {"bold": True}))
        for why, names in reasons.items():
            out.append((f"  {why}", {"yellow": True}))
            out.append((f"    {', '.join(names)}", {}))
    if rep.infos:
        out.append(("", {}))
        out.append(("information (docs/protocol.md is silent here; never a failure):", {"bold": True}))
        for i in rep.infos:
            out.append((f"  {i.topic}: {i.observed}", {}))
    if rep.timing:
        out.append(("", {}))
        out.append(("answer turnaround (ms)   count     min  median     max", {"bold": True}))
        for h, n, lo, med, hi in rep.timing:
            out.append((f"  {h:<22} {n:>5} {lo * 1e3:>7.1f} {med * 1e3:>7.1f} {hi * 1e3:>7.1f}", {}))
    out.append(("", {}))
    for line in rep.safety:
        out.append((f"safety: {line}", {}))
    for line in rep.safety_warnings:
        out.append((f"safety note: {line}", {"yellow": True}))
    for line in rep.safety_problems:
        out.append((f"safety PROBLEM: {line}", {"red": True, "bold": True}))
    for line in rep.safety_unverified:
        out.append((f"safety NOT RESTORED: {line}", {"red": True, "bold": True}))
    if rep.not_run_checks:
        out.append((f"not run: {_grouped(rep.not_run_checks)}", {"yellow": True}))
    if rep.abort:
        out.append((f"run stopped: {rep.abort}", {"red": True, "bold": True}))
    out.append((rep.verdict_line, {"green" if rep.accepted else "red": True, "bold": True}))
    return out


def _not_run_count(rep: Report) -> str:
    info = sum(name.endswith(" (information)") for name, _ in rep.not_run_checks)
    rules = f"{len(rep.not_run_checks) - info} check(s) of stated rules"
    return rules + (f" and {info} information record(s)" if info else "")


def _grouped(checks: list[tuple[str, str]]) -> str:
    """Check names, parametrized ones counted under their base name: ``malformed_answered (16)``."""
    counts: dict[str, int] = {}
    for name, why in checks:
        key = name.split("[")[0] + (" (interrupted)" if why.startswith("interrupted") else "")
        counts[key] = counts.get(key, 0) + 1
    return ", ".join(k if c == 1 else f"{k} ({c})" for k, c in counts.items())


# ---- files ----

def _md_code(text: str) -> str:
    text = text.replace("|", "\\|")
    return f"`` {text} ``" if "`" in text else f"`{text}`"


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def markdown(rep: Report) -> str:
    o: list[str] = ["# XA-C1 conformance report", "", f"**Verdict: {rep.verdict_line}**", ""]
    o += ["This report says whether the controller follows every rule the XA-C1 protocol states "
          "(docs/protocol.md, a restatement of the vendor's text). Each check below names the rule, the "
          "verdict and the bytes the test sent and received (`\\r` is CR, `\\n` is LF). Skipped checks "
          "could not be done on this run (the reason says what to pass); they do not count against the "
          "device. The information section shows what the device does where the protocol leaves the choice "
          "open: it never fails a device.", ""]
    o += ["## Device and run", "", "| | |", "|---|---|", f"| firmware version | {rep.version} |",
          f"| date | {rep.date} |"]
    o += [f"| {k} | {_md_cell(v)} |" for k, v in rep.options]
    if rep.abort:
        o += ["", f"**The run stopped early:** {_md_cell(rep.abort)}"]
    o += ["", "## Verdicts", "",
          "| check | rule | docs/protocol.md | verdict | evidence (sent -> received) |",
          "|---|---|---|---|---|"]
    for r in rep.checks:
        ev = "<br>".join(_md_code(p.show()) for p in r.probes[:2]) or _md_cell(r.message or "-")
        if len(r.probes) > 2:
            ev += f"<br>(+{len(r.probes) - 2} more)"
        o.append(f"| {_md_cell(r.check)} | {_md_cell(r.rule)} | {_md_cell(r.section)} | **{r.verdict}** "
                 f"| {ev} |")
    if rep.failed:
        o += ["", "## Failures in detail", ""]
        for r in rep.failed:
            cited = r.section and "docs/protocol.md" not in r.rule
            where = f" (docs/protocol.md {r.section})" if cited else ""
            o += [f"### {r.verdict}: {_md_cell(r.check)}", "", f"Rule: {r.rule}{where}", "",
                  f"What happened: {r.message}", ""]
            o += ["Exchanges:", ""] + [f"- {_md_code(p.show())}" for p in r.probes[:EVIDENCE_LIMIT]]
            if len(r.probes) > EVIDENCE_LIMIT:
                o.append(f"- ... {len(r.probes) - EVIDENCE_LIMIT} more")
            o.append("")
    if rep.all_skipped:
        o += ["", "## Skipped checks", "", "Not a failure: the run could not do what these need. "
              "The reason says what to pass to run them.", "", "| check | why |", "|---|---|"]
        o += [f"| {_md_cell(r.check)}{' (information)' if r.info else ''} | {_md_cell(r.message)} |"
              for r in rep.all_skipped]
    if rep.not_run_checks:
        o += ["", "## Checks not run", "",
              f"The run did not complete (see above): these {_not_run_count(rep)} have no verdict.", "",
              "| check | |", "|---|---|"]
        o += [f"| {_md_cell(name)} | {_md_cell(why)} |" for name, why in rep.not_run_checks]
    elif rep.not_run:
        o += ["", f"**{rep.not_run} check(s) were not run:** the run stopped early (see above)."]
    o += ["", "## Information (the protocol is silent here; never a failure)", ""]
    if rep.infos:
        o += ["| topic | docs/protocol.md | what the device did | exchanges |", "|---|---|---|---|"]
        for i in rep.infos:
            ev = "<br>".join(_md_code(p.show()) for p in i.probes[:3]) or "-"
            o.append(f"| {_md_cell(i.topic)} | {_md_cell(i.section)} | {_md_cell(i.observed)} | {ev} |")
    else:
        o.append("Nothing recorded.")
    for r in rep.info_errors:
        o.append(f"\nCould not record {r.check}: {_md_cell(r.message)}")
    o += ["", "## Answer turnaround", "",
          "Time from the command's last byte to the answer's first byte. Moves (0MP, 0MV) include the "
          "move itself.", "", "| command | answers | min (ms) | median (ms) | max (ms) |",
          "|---|---|---|---|---|"]
    o += [f"| {h} | {n} | {lo * 1e3:.1f} | {med * 1e3:.1f} | {hi * 1e3:.1f} |"
          for h, n, lo, med, hi in rep.timing] or ["| (no answer was received) | 0 | | | |"]
    o += ["", "## Safety", ""] + [f"- {line}" for line in rep.safety]
    o += [f"- Note: {line}" for line in rep.safety_warnings]
    o += [f"- **PROBLEM:** {line}" for line in rep.safety_problems]
    o += [f"- **NOT RESTORED:** {line}" for line in rep.safety_unverified]
    return "\n".join(o) + "\n"


_CSS = ("body{font-family:sans-serif;max-width:70em;margin:2em auto;padding:0 1em;color:#222}"
        "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:.25em .5em;"
        "vertical-align:top;text-align:left}code{font-size:.9em;background:#f3f3f3}"
        ".PASS{color:#070}.FAIL,.ERROR{color:#b00;font-weight:bold}.SKIP{color:#a60}"
        ".verdict{font-size:1.2em;font-weight:bold;padding:.5em;border:2px solid}")


def _h(text: object) -> str:
    return html.escape(str(text))


def _hcode(p: Probe) -> str:
    return f"<code>{_h(p.show())}</code>"


def html_page(rep: Report) -> str:
    o = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>XA-C1 conformance report</title>"
         f"<style>{_CSS}</style></head><body><h1>XA-C1 conformance report</h1>",
         f"<p class='verdict {'PASS' if rep.accepted else 'FAIL'}'>{_h(rep.verdict_line)}</p>",
         "<p>This report says whether the controller follows every rule the XA-C1 protocol states. Each "
         "check names the rule, the verdict and the bytes sent and received (<code>\\r</code> is CR, "
         "<code>\\n</code> is LF). Skipped checks could not be done on this run (the reason says what to "
         "pass) and do not count against the device. The information section shows what the device does "
         "where the protocol leaves the choice open: it never fails a device.</p>",
         "<h2>Device and run</h2><table>",
         f"<tr><th>firmware version</th><td>{_h(rep.version)}</td></tr>",
         f"<tr><th>date</th><td>{_h(rep.date)}</td></tr>"]
    o += [f"<tr><th>{_h(k)}</th><td>{_h(v)}</td></tr>" for k, v in rep.options]
    o.append("</table>")
    if rep.abort:
        o.append(f"<p class='FAIL'>The run stopped early: {_h(rep.abort)}</p>")
    o.append("<h2>Verdicts</h2><table><tr><th>check</th><th>rule</th><th>docs/protocol.md</th><th>verdict</th>"
             "<th>evidence (sent -&gt; received)</th></tr>")
    for r in rep.checks:
        ev = "<br>".join(_hcode(p) for p in r.probes[:EVIDENCE_LIMIT])
        if r.message:
            ev = f"<div>{_h(r.message)}</div>" + ev
        if len(r.probes) > EVIDENCE_LIMIT:
            ev += f"<br>... {len(r.probes) - EVIDENCE_LIMIT} more"
        o.append(f"<tr><td>{_h(r.check)}</td><td>{_h(r.rule)}</td><td>{_h(r.section)}</td>"
                 f"<td class='{r.verdict}'>{r.verdict}</td><td>{ev or '-'}</td></tr>")
    o.append("</table>")
    if rep.all_skipped:
        o.append("<h2>Skipped checks</h2><p>Not a failure: the run could not do what these need. "
                 "The reason says what to pass to run them.</p><table><tr><th>check</th><th>why</th></tr>")
        o += [f"<tr><td>{_h(r.check)}{' (information)' if r.info else ''}</td><td>{_h(r.message)}</td></tr>"
              for r in rep.all_skipped]
        o.append("</table>")
    if rep.not_run_checks:
        o.append(f"<h2>Checks not run</h2><p class='FAIL'>The run did not complete: these "
                 f"{_not_run_count(rep)} have no verdict.</p><table>")
        o += [f"<tr><td>{_h(name)}</td><td>{_h(why)}</td></tr>" for name, why in rep.not_run_checks]
        o.append("</table>")
    elif rep.not_run:
        o.append(f"<p class='FAIL'>{rep.not_run} check(s) were not run: the run stopped early.</p>")
    o.append("<h2>Information (the protocol is silent here; never a failure)</h2>")
    if rep.infos:
        o.append("<table><tr><th>topic</th><th>docs/protocol.md</th><th>what the device did</th>"
                 "<th>exchanges</th></tr>")
        for i in rep.infos:
            o.append(f"<tr><td>{_h(i.topic)}</td><td>{_h(i.section)}</td><td>{_h(i.observed)}</td>"
                     f"<td>{'<br>'.join(_hcode(p) for p in i.probes[:3]) or '-'}</td></tr>")
        o.append("</table>")
    else:
        o.append("<p>Nothing recorded.</p>")
    for r in rep.info_errors:
        o.append(f"<p>Could not record {_h(r.check)}: {_h(r.message)}</p>")
    o.append("<h2>Answer turnaround</h2><p>From the command's last byte to the answer's first byte; moves "
             "include the move itself.</p><table><tr><th>command</th><th>answers</th><th>min (ms)</th>"
             "<th>median (ms)</th><th>max (ms)</th></tr>")
    o += [f"<tr><td>{_h(h)}</td><td>{n}</td><td>{lo * 1e3:.1f}</td><td>{med * 1e3:.1f}</td>"
          f"<td>{hi * 1e3:.1f}</td></tr>" for h, n, lo, med, hi in rep.timing] or [
        "<tr><td colspan='5'>no answer was received</td></tr>"]
    o.append("</table><h2>Safety</h2><ul>")
    o += [f"<li>{_h(line)}</li>" for line in rep.safety]
    o += [f"<li class='SKIP'>Note: {_h(line)}</li>" for line in rep.safety_warnings]
    o += [f"<li class='FAIL'>PROBLEM: {_h(line)}</li>" for line in rep.safety_problems]
    o += [f"<li class='FAIL'>NOT RESTORED: {_h(line)}</li>" for line in rep.safety_unverified]
    o.append("</ul></body></html>")
    return "\n".join(o) + "\n"


def write_file(path: Path, rep: Report) -> None:
    """Markdown or HTML by the file's suffix."""
    text = html_page(rep) if path.suffix.lower() in (".html", ".htm") else markdown(rep)
    path.write_text(text, encoding="utf-8")


__all__ = ["Report", "Result", "build", "html_page", "markdown", "result_from", "terminal_lines", "wire",
           "write_file"]
