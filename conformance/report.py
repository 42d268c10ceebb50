"""A run's verdict as one data model (``Report``) and the ways to show it: terminal lines, Markdown and
HTML (Jinja2 templates ``conformance.md.j2`` / ``conformance.html.j2`` through ``xac1_proto.pages``).

How it works: ``build`` gathers a finished (or interrupted) run into a ``Report``; ``Report.verdict``
decides the head word and ``exit_status`` the exit code, the writers only format. The verdict is
honest: ``CONFORMS`` only when every check of a stated rule that can run over the line ran and passed
(a check only a person can do is listed as a manual step); a run with no failure but checks not run is
``INCOMPLETE: N of M checks not run`` naming the options that would run them (exit 4). The report is
written for someone who has never seen pytest: the unit and who tested it, the command line, a summary by
rule group, failures before passes, and what the device did where docs/protocol.md is silent.
"""

from __future__ import annotations

import re
import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from .results import ERROR, FAIL, MANUAL, PASS, SKIP, Result, result_from

EVIDENCE_LIMIT = 12  # probes listed per check in the report file
EXIT_OK, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_COULD_NOT_GO_ON, EXIT_INCOMPLETE = 0, 1, 2, 3, 4
# Turnaround under this is what an in-process or time-scaled simulator gives: not worth a table.
MEANINGFUL_TURNAROUND_S = 0.001
_OPTION = re.compile(r"(--[a-z][a-z0-9-]*(?: (?:LO:HI|S|[0-9A-F][0-9A-Fa-fx,:]*))?)")
GROUP_TITLES = {
    "power_on": "power-on behaviour", "alarms": "alarm latching and reset", "echo": "echo answers",
    "framing": "framing of answers", "malformed": "malformed commands", "motion": "moves",
    "outputs": "OUT ports", "points": "position table", "version": "firmware version",
    "properties": "random command sequences", "information": "information (silent points)",
}


@dataclass
class Group:
    """The checks of one rule group (a check module): counts for the summary."""

    topic: str
    title: str
    passed: int = 0
    failed: int = 0
    skipped: int = 0
    manual: int = 0
    not_run: int = 0

    @property
    def verdict(self) -> str:
        if self.failed:
            return FAIL
        if self.skipped or self.not_run:
            return SKIP
        return PASS


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
    not_run: int = 0  # checks of stated rules collected but never run (the run stopped early)
    info_skipped: list[Result] = field(default_factory=list)
    stopped: bool = False  # the device answered, then stopped answering (or its port failed)
    safety_unverified: list[str] = field(default_factory=list)  # the restore could not be done or checked
    not_run_checks: list[tuple[str, str]] = field(default_factory=list)  # (check, interrupted or not run)
    interrupted: str | None = None  # the signal that ended the run (SIGINT, SIGTERM, SIGHUP)
    deselected: int = 0  # checks of stated rules left out with -k
    unit: list[tuple[str, str]] = field(default_factory=list)  # unit id, operator, station, note
    command_line: str = ""
    seed: int | None = None
    kit_version: str = ""
    junit: list[Result] = field(default_factory=list)  # every result, information included
    not_run_topics: list[str] = field(default_factory=list)  # the group of each stated-rule check not run
    latencies: dict[str, list[float]] = field(default_factory=dict)  # command header -> turnarounds (s)
    timeout: float | None = None  # the run's answer timeout (s): the deadline drawn on the histogram
    readings: str = "notice"  # the severity of our readings (--readings): only errors fail a device
    restore_failed: list[str] = field(default_factory=list)  # what the restore wrote back but reads wrong
    restore_unverified: list[str] = field(default_factory=list)  # what the run changed, not restored

    # ---- what the checks say ----

    @property
    def failed(self) -> list[Result]:
        return [r for r in self.checks if r.verdict in (FAIL, ERROR)]

    @property
    def passed(self) -> list[Result]:
        return [r for r in self.checks if r.verdict == PASS]

    @property
    def skipped(self) -> list[Result]:
        return [r for r in self.checks if r.verdict == SKIP]

    @property
    def manual(self) -> list[Result]:
        return [r for r in self.checks if r.verdict == MANUAL]

    @property
    def all_skipped(self) -> list[Result]:
        """Skipped checks of stated rules, then skipped checks that record information."""
        return self.skipped + self.info_skipped

    @property
    def ordered(self) -> list[Result]:
        """Failures first, then skipped, manual, passed (file order within each)."""
        rank = {FAIL: 0, ERROR: 0, SKIP: 1, MANUAL: 2, PASS: 3}
        return sorted(self.checks, key=lambda r: rank[r.verdict])

    @property
    def total(self) -> int:
        """Checks of stated rules this run could do over the line (manual steps not counted)."""
        return len(self.checks) - len(self.manual) + self.not_run + self.deselected

    @property
    def missing(self) -> int:
        """Checks of stated rules that have no verdict: skipped, not run, deselected."""
        return len(self.skipped) + self.not_run + self.deselected

    @property
    def to_run_them(self) -> list[str]:
        """The options named by the skip reasons (what would run the skipped checks)."""
        out: dict[str, str] = {}  # option name -> the widest value asked for
        for r in self.all_skipped:
            for opt in _OPTION.findall(r.message):
                name = opt.split(" ")[0]
                if len(opt) > len(out.get(name, "")):
                    out[name] = opt
        hints = list(out.values())
        if self.deselected:
            hints.append("no -k")
        return hints

    @property
    def accepted(self) -> bool:
        return self.head == "CONFORMS"

    @property
    def head(self) -> str:
        if self.no_answer and not self.failed:
            return "NO ANSWER FROM THE DEVICE"
        if self.failed or self.safety_problems:
            return "DOES NOT CONFORM"
        if self.stopped:
            return "THE DEVICE STOPPED ANSWERING"
        if self.abort and not self.interrupted:
            return "NOT TESTED" if not self.passed else "COULD NOT GO ON"
        if self.interrupted or self.missing or self.safety_unverified or not self.passed:
            return "INCOMPLETE"
        return "CONFORMS"

    @property
    def verdict_line(self) -> str:
        head, n = self.head, len(self.passed)
        if head == "NO ANSWER FROM THE DEVICE":
            return f"{head}: nothing could be checked ({self.total} checks not run)"
        counts = f"{n} passed, {len(self.failed)} failed"
        if self.missing:
            counts += f", {self.missing} not run"
        counts += f" (of {self.total} checks of stated rules)"
        if self.manual:
            counts += f"; {len(self.manual)} manual step(s) for the operator (see the report)"
        if head == "INCOMPLETE" and not self.interrupted and self.missing:
            line = f"INCOMPLETE: {self.missing} of {self.total} checks not run"
            hints = self.to_run_them
            if hints:
                line += f"; to run them: {', '.join(hints)}"
            return line + f" ({counts})"
        line = f"{head}: {counts}"
        if self.interrupted:
            left_out = f"{self.deselected} of them left out with -k; " if self.deselected else ""
            line = (f"INCOMPLETE: {self.missing} of {self.total} checks not run ({left_out}the run was "
                    f"interrupted by {self.interrupted})") if head == "INCOMPLETE" else line + \
                f" (the run was interrupted by {self.interrupted})"
        elif head == "THE DEVICE STOPPED ANSWERING":
            when = "the run did not complete" if self.abort else "during the restore, after the checks"
            line = f"{head}: {when} ({counts})"
        elif head == "COULD NOT GO ON":
            line += "; the run stopped early (see why above)"
        line += f"; readings: {self.readings}"  # which --readings judged it (the restore's news stays last)
        if self.safety_problems:
            what = ", ".join(self.restore_failed) or self.safety_problems[0]
            line += f"; THE RESTORE FAILED ({what}; see the safety section)"
        if self.safety_unverified:
            what = ", ".join(self.restore_unverified)
            line += (f"; THE DEVICE COULD NOT BE RESTORED (not verified: {what}; see the safety section)"
                     if what else "; THE DEVICE COULD NOT BE RESTORED (see the safety section)")
        return line

    def exit_status(self, allow_incomplete: bool = False) -> int:
        head = self.head
        if self.interrupted:
            return EXIT_INTERRUPTED
        if head == "DOES NOT CONFORM":
            return EXIT_FAILED
        could_not = ("NO ANSWER FROM THE DEVICE", "THE DEVICE STOPPED ANSWERING", "COULD NOT GO ON",
                     "NOT TESTED")
        if head in could_not or self.safety_unverified:
            return EXIT_COULD_NOT_GO_ON
        if head == "INCOMPLETE":
            return EXIT_OK if allow_incomplete else EXIT_INCOMPLETE
        return EXIT_OK

    # ---- summaries ----

    @property
    def groups(self) -> list[Group]:
        """One line per rule group (check module), in run order."""
        out: dict[str, Group] = {}
        for r in self.checks:
            g = out.setdefault(r.topic, Group(r.topic, GROUP_TITLES.get(r.topic, r.topic.replace("_", " "))))
            if r.verdict == PASS:
                g.passed += 1
            elif r.verdict in (FAIL, ERROR):
                g.failed += 1
            elif r.verdict == MANUAL:
                g.manual += 1
            else:
                g.skipped += 1
        for topic in self.not_run_topics:
            out.setdefault(topic, Group(topic, GROUP_TITLES.get(topic, topic.replace("_", " ")))).not_run += 1
        return list(out.values())

    @property
    def timing_meaningful(self) -> bool:
        """Turnaround statistics mean something only when answers took measurable time."""
        medians = sorted(med for _h, _n, _lo, med, _hi in self.timing)
        return bool(medians) and medians[len(medians) // 2] >= MEANINGFUL_TURNAROUND_S

    @property
    def skip_reasons(self) -> list[tuple[str, list[str]]]:
        reasons: dict[str, list[str]] = {}
        for r in self.all_skipped:
            reasons.setdefault(r.message, []).append(r.check + (" (information)" if r.info else ""))
        return list(reasons.items())


# how the report's options name the --readings setting (docs/protocol.md "Violation codes")
_READINGS_TEXT: Final = {"notice": "notice (our readings of the silent vendor text never fail a device)",
                         "error": "error (our readings of the silent vendor text fail a device too)"}


def build(run: Any) -> Report:
    """Gather a finished (or interrupted) run into a ``Report``."""
    from xac1_proto import __version__

    s = run.settings
    checks = [r for r in run.results if not r.info]
    info_errors = [r for r in run.results if r.info and r.verdict in (FAIL, ERROR)]
    info_skipped = [r for r in run.results if r.info and r.verdict == SKIP]
    run_checks = run.total - run.total_info
    safety, problems, warnings, unverified = _safety(run)
    rr = run.restore_report
    restore_failed, restore_unverified = ((list(rr.failed_items), list(rr.unverified_items))
                                          if rr is not None else ([], []))
    not_run_checks, not_run_topics = _not_reached(run)
    return Report(
        port=s.port, date=run.started.strftime("%Y-%m-%d %H:%M:%S %Z"), options=_options(run, __version__),
        checks=checks, info_errors=info_errors, safety=safety, safety_problems=problems,
        abort=run.abort, safety_warnings=warnings, no_answer=run.no_answer,
        not_run=max(run_checks - len(checks), 0), info_skipped=info_skipped,
        stopped=run.stopped or bool(unverified), safety_unverified=unverified, not_run_checks=not_run_checks,
        interrupted=run.interrupted_by, deselected=run.deselected, unit=_unit(run.identity),
        command_line=run.command_line or shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        seed=s.seed, kit_version=__version__, junit=list(run.results),
        not_run_topics=not_run_topics,
        timeout=s.timeout, readings=s.readings, restore_failed=restore_failed,
        restore_unverified=restore_unverified,
        **_device_facts(run.dut))


def _not_reached(run: Any) -> tuple[list[tuple[str, str]], list[str]]:
    """The checks collected that got no verdict: each (name, "interrupted: ..." when the run stopped
    during it, else "not run"), and the topic of each such check of a stated rule."""
    judged = {r.nodeid for r in run.results}
    unjudged = [(nodeid, name, info) for nodeid, name, info in run.collected if nodeid not in judged]
    cut = "interrupted: the run stopped during this check"
    checks = [(name + (" (information)" if info else ""), cut if nodeid in run.interrupted else "not run")
              for nodeid, name, info in unjudged]
    return checks, [_topic(nodeid) for nodeid, _name, info in unjudged if not info]


IDENTITY: Final = (("unit id", "unit_id"), ("operator", "operator"), ("station", "station"), ("note", "note"))


def _unit(identity: dict[str, str | None]) -> list[tuple[str, str]]:
    """The unit's identity as the report's rows (label, value), those given only."""
    return [(label, value) for label, key in IDENTITY if (value := identity.get(key))]


def _options(run: Any, kit_version: str) -> list[tuple[str, str]]:
    """The run's settings as the report's options table shows them."""
    s = run.settings
    return [
        ("port", s.port + ("  (the built-in simulator)" if s.simulator else "")),
        ("motion", "allowed" if s.motion else "not allowed (motion checks skipped)"),
        ("safe range", s.describe_range()),
        ("fresh device", "yes (power-on checks run first)" if s.fresh else "no (power-on checks skipped)"),
        ("random sequences", f"{s.examples} (seed {s.seed if s.seed is not None else 'derandomized'})"),
        ("answer timeout", f"{s.timeout:g} s"),
        ("readings", _READINGS_TEXT[s.readings]),
        ("points the suite may write", _scratch_text(run)),
        ("kit", f"xac1-proto {kit_version}"),
    ]


def _device_facts(dut: Any) -> dict[str, Any]:
    """What the device under test told the run (its version, information answers, turnaround); the
    same fields empty when the device was never opened."""
    if dut is None:
        return {"version": "unknown", "infos": [], "timing": [], "latencies": {}}
    return {"version": dut.version or "unknown", "infos": list(dut.infos), "timing": dut.timing_table(),
            "latencies": {h: list(v) for h, v in dut.latencies.items() if v}}


def _topic(nodeid: str) -> str:
    return Path(nodeid.split("::")[0]).stem.removeprefix("test_")


def _safety(run: Any) -> tuple[list[str], list[str], list[str], list[str]]:
    safety: list[str] = []
    problems: list[str] = []
    if run.snapshot is not None:
        snap = run.snapshot
        safety.append(f"Before the first write the suite read all {len(snap.points)} points, the OUT ports "
                      f"({snap.outputs}) and the position ({snap.position_seen}).")
    elif run.dut is None:
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
        unverified += rr.unverified
    elif run.snapshot is not None:
        problems.append("the device was not restored (the run ended before the restore step)")
    return safety, problems, warnings, unverified


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

Lines = list[tuple[str, str]]  # (line, style) pairs


def terminal_lines(rep: Report) -> Lines:
    """What the operator reads at the end of a run, as (line, style) pairs: style is '', 'good', 'bad',
    'warn' or 'bold'. Nothing is cut: long lines wrap on the terminal. An early stop tested nothing:
    it gets no block about checks."""
    tested = bool(rep.passed or rep.failed)
    out: Lines = []
    for section in _SECTIONS_OF_ANY_RUN if not tested else _SECTIONS_OF_A_TESTED_RUN:
        out += section(rep)
    out.append((rep.verdict_line, "good" if rep.accepted else "bad"))
    return out


def _head_and_failures(rep: Report) -> Lines:
    """The unit and the run's head line, then each failed check with its first probes."""
    out: Lines = [(f"firmware {rep.version} on {rep.port}  |  {rep.date}", "bold")]
    out += [(f"{k}: {v}", "") for k, v in rep.unit]
    for r in rep.failed:
        out += [("", ""), (f"{r.verdict} {r.check}: {r.rule}", "bad"), (f"  {r.message}", "")]
        out += [(f"    {p.show()}", "") for p in r.probes[:6]]
    return out


_GROUP_STYLE = {FAIL: "bad", SKIP: "warn", PASS: "good"}


def _groups(rep: Report) -> Lines:
    """One line per rule group: its verdict and counts."""
    out: Lines = [("", ""), ("by rule group:", "bold")]
    for g in rep.groups:
        parts = [f"{g.passed} passed"] + [f"{n} {w}" for n, w in ((g.failed, "failed"),
                 (g.skipped + g.not_run, "not run"), (g.manual, "manual")) if n]
        out.append((f"  {g.verdict:<4}  {g.title}: {', '.join(parts)}", _GROUP_STYLE[g.verdict]))
    return out


def _skips(rep: Report) -> Lines:
    """The checks not run, grouped by why, with what would run them."""
    if not rep.skip_reasons:
        return []
    out: Lines = [("", ""), ("checks not run (never a failure, but not an acceptance either); to run them:",
                              "bold")]
    for why, names in rep.skip_reasons:
        out += [(f"  {why}", "warn"), (f"    {_grouped([(n, '') for n in names])}", "")]
    return out


def _manual_steps(rep: Report) -> Lines:
    """The steps only a person can do."""
    return [(f"manual step ({r.check}): {r.message}", "warn") for r in rep.manual]


def _information(rep: Report) -> Lines:
    """What the device did where docs/protocol.md is silent."""
    if not rep.infos:
        return []
    checks = sum(1 for r in rep.junit if r.info)
    head = (f"information: {_records(len(rep.infos), checks)} (docs/protocol.md is silent here; "
            f"never a failure):")
    return [("", ""), (head, "bold")] + [(f"  {i.topic}: {i.observed}", "") for i in rep.infos]


def _turnaround(rep: Report) -> Lines:
    """The answer turnaround per command, when it means something (a real line, not a fast simulator)."""
    if not (rep.timing and rep.timing_meaningful):
        return []
    return [("", ""), ("answer turnaround (ms)   count     min  median     max", "bold")] + [
        (f"  {h:<22} {n:>5} {lo * 1e3:>7.1f} {med * 1e3:>7.1f} {hi * 1e3:>7.1f}", "")
        for h, n, lo, med, hi in rep.timing]


def _safety_lines(rep: Report) -> Lines:
    """What the run did to the device and whether it was put back."""
    return ([("", "")] + [(f"safety: {line}", "") for line in rep.safety]
            + [(f"safety note: {line}", "warn") for line in rep.safety_warnings]
            + [(f"safety PROBLEM: {line}", "bad") for line in rep.safety_problems]
            + [(f"safety NOT RESTORED: {line}", "bad") for line in rep.safety_unverified])


def _not_run(rep: Report) -> Lines:
    """The checks collected but never run (the run stopped first)."""
    return [(f"not run: {_grouped(rep.not_run_checks)}", "warn")] if rep.not_run_checks else []


def _abort(rep: Report) -> Lines:
    """Why the run stopped, when it stopped early."""
    return [(f"run stopped: {rep.abort}", "bad")] if rep.abort else []


# The terminal summary's sections in order; the blocks about checks only when a check ran.
_SECTIONS_OF_A_TESTED_RUN: Final = (_head_and_failures, _groups, _skips, _manual_steps, _information,
                                    _turnaround, _safety_lines, _not_run, _abort)
_SECTIONS_OF_ANY_RUN: Final = (_head_and_failures, _manual_steps, _information, _turnaround, _safety_lines,
                               _abort)


def _records(records: int, checks: int) -> str:
    """``19 records from 9 checks``: the count of the information lines that follow, and of the checks
    that recorded them (the count the run's first line gives)."""
    made = f"{records} record{'s' if records != 1 else ''}"
    return f"{made} from {checks} check{'s' if checks != 1 else ''}" if checks else made


def _grouped(checks: list[tuple[str, str]]) -> str:
    """Check names, parametrized ones counted under their base name: ``malformed_answered (16)``."""
    counts: dict[str, int] = {}
    for name, why in checks:
        key = name.split("::")[-1].split("[")[0] + (" (interrupted)" if why.startswith("interrupted") else "")
        counts[key] = counts.get(key, 0) + 1
    return ", ".join(k if c == 1 else f"{k} ({c})" for k, c in counts.items())


# ---- files ----

def _md(text: object) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _md_code(text: str) -> str:
    text = text.replace("|", "\\|")
    return f"`` {text} ``" if "`" in text else f"`{text}`"


PICTURES_HINT = "pip install 'xac1-proto[report]'"  # the extra that draws the report's pictures


def pictures(rep: Report) -> dict[str, Any] | None:
    """The HTML report's figures (issue 17): the rule groups as stacked bars and, when turnaround means
    something (``timing_meaningful``), its histogram per command with the answer deadline, drawn by the
    reports' plotly fragments (``xac1_proto.pages.figures``), with plotly.js to inline once. None when
    plotly (the ``report`` extra) is not installed: the page is then the same without the pictures."""
    import html

    from markupsafe import Markup

    try:
        from xac1_proto.pages import figures
    except ImportError:
        return None
    # Names reach plotly's labels, which read HTML: escaped, as the page's own text is.
    outcomes = {html.escape(g.title): {"passed": g.passed, "failed": g.failed,
                                       "skipped": g.skipped + g.not_run, "manual": g.manual}
                for g in rep.groups}
    groups = {title: {k: n for k, n in counts.items() if n} for title, counts in outcomes.items()}
    turnaround = None
    if rep.latencies and rep.timing_meaningful:
        deadline = rep.timeout * 1000.0 if rep.timeout is not None else None
        turnaround = Markup(figures.turnaround_histogram(
            {html.escape(h): [t * 1000.0 for t in v] for h, v in rep.latencies.items()},
            title="Answer turnaround per command", deadline_ms=deadline))
    summary = Markup(figures.group_summary(groups, title="Checks per rule group")) if groups else None
    return {"groups": summary,
            "turnaround": turnaround,
            "js": Markup(figures.plotly_js().replace("</script", "<\\/script"))}


def render_page(rep: Report, kind: str) -> str:
    """The report as ``html`` or ``md`` text."""
    from xac1_proto.pages import environment, render

    env = environment()
    env.filters.setdefault("md", _md)
    env.filters.setdefault("mdcode", _md_code)
    return render(f"conformance.{kind}.j2", rep=rep, title="XA-C1 conformance report",
                  limit=EVIDENCE_LIMIT, not_run_text=_not_run_count(rep),
                  pictures=pictures(rep) if kind == "html" else None, pictures_hint=PICTURES_HINT)


def html_page(rep: Report) -> str:
    return render_page(rep, "html")


def markdown(rep: Report) -> str:
    return render_page(rep, "md")


def _not_run_count(rep: Report) -> str:
    info = sum(name.endswith(" (information)") for name, _ in rep.not_run_checks)
    rules = f"{len(rep.not_run_checks) - info} check(s) of stated rules"
    return rules + (f" and {info} check(s) that record information" if info else "")


def kind_of(path: Path) -> str | None:
    """``html``, ``md`` or ``xml`` by the file's suffix (None: not a report name)."""
    return {".html": "html", ".htm": "html", ".md": "md", ".markdown": "md", ".xml": "xml"}.get(
        path.suffix.lower())


def write_file(path: Path, rep: Report) -> None:
    """Markdown or HTML by the file's suffix, written atomically to the file ``path`` names."""
    from xac1_proto.output_file import write_output

    write_output(path, html_page(rep) if kind_of(path) == "html" else markdown(rep))  # through a link


__all__ = ["Report", "Result", "build", "html_page", "markdown", "result_from", "terminal_lines",
           "write_file"]
