"""``xac1 fuzz``: how a controller stands up to a hostile line, found, shrunk and replayable, never a move.

A thin shell: the options are checked before anything is sent; the unit's points, OUT ports and position
are read first (``xac1_proto.dut.safety``) and put back at the end however the run ends (SIGINT, SIGTERM
and SIGHUP end the run in order: ``xac1_proto.signals``); the cases, the probes and the shrinking are
``fuzz_run.FuzzRun`` over ``fuzz_unit.Unit``, the judging is the sans-IO core ``xac1_proto.fuzz``; what
is written is ``fuzz_files``; the run's history record is ``fuzz_history``. A live progress bar on a
terminal (stderr), the results on stdout.

Exit status: 0 no finding; 1 findings; 2 bad options, or a signal before the first case; 3 the unit could
not be reached or never answered at the start.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from typing import TYPE_CHECKING, Any, Final, TextIO

if TYPE_CHECKING:
    import datetime as _dt

    from xac1_proto.chunk import Chunk
    from xac1_proto.dut.settings import Settings
    from xac1_proto.fuzz.results import CaseResult, Reported, RunSummary

HELP = ("send hostile lines (never a move) to a controller (default: the simulator) and report what it "
        "does not stand up to")
PROGRAM: Final = "xac1 fuzz"
EXIT_CLEAN, EXIT_FINDINGS, EXIT_USAGE, EXIT_DEVICE = 0, 1, 2, 3
DEFAULT_CASES: Final = 200


def _positive(kind: type) -> Any:
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a {'number' if kind is float else 'count'}") \
                from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"{text!r}: give a value above 0")
        return value
    return parse


def _count0(text: str) -> int:
    if not text.isdigit():
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number >= 0")
    return int(text)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", metavar="URL", default=None,
                   help="the unit: a serial port path or any pyserial URL (default: the built-in simulator, "
                        "xac1sim://?time_scale=0)")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the cases (default: a new one, printed in the summary; the same seed "
                        "sends the same cases)")
    how_long = p.add_mutually_exclusive_group()
    how_long.add_argument("--cases", type=_positive(int), metavar="N", default=None,
                          help=f"run N cases (default {DEFAULT_CASES})")
    how_long.add_argument("--seconds", type=_positive(float), metavar="S", default=None,
                          help="run cases for S seconds")
    p.add_argument("--allow-motion", action="store_true",
                   help="mix in well-formed direct moves inside --safe-range (never otherwise a move)")
    p.add_argument("--safe-range", metavar="LO:HI", default=None,
                   help="positions the actuator may be moved to (decimal or 0x-hex), with --allow-motion")
    p.add_argument("--timeout", type=_positive(float), metavar="S", default=None,
                   help="the answer window of each line and probe (default 1; with xac1sim://: 0.2)")
    p.add_argument("--state-every", type=_positive(int), metavar="N", default=20,
                   help="read the points and OUT ports back every N cases (and at the end; default 20)")
    p.add_argument("--max-findings", type=_positive(int), metavar="N", default=5,
                   help="end the run after N findings (default 5)")
    p.add_argument("--shrink-budget", type=_count0, metavar="N", default=150,
                   help="re-runs spent shrinking each finding (default 150; 0: report as found)")
    p.add_argument("--save", metavar="DIR", default=None,
                   help="write each finding as a capture (JSON lines recording) that xac1 replay plays")
    p.add_argument("--format", "-f", choices=("text", "jsonl"), default="text",
                   help="findings and summary as text (default), or JSON lines (a line per case too)")
    p.add_argument("--report", metavar="FILE", default=None,
                   help="also write a report: Markdown when FILE ends in .md, else HTML")
    p.add_argument("--junit", metavar="FILE", default=None,
                   help="also write JUnit XML (one test case a kind of finding)")
    p.add_argument("--restore-mode0", action="store_true",
                   help="send 0CM0 as the very last command (external start inputs enabled again)")
    from xac1_proto.history.command import add_arguments as history_arguments

    history_arguments(p, "the fuzz run")


def _error(message: str, status: int = EXIT_USAGE) -> int:
    print(f"{PROGRAM}: {message}", file=sys.stderr)
    return status


def _settings(args: argparse.Namespace) -> Settings:
    from xac1_proto.dut.settings import Settings, SettingsError, parse_safe_range

    if args.safe_range is not None:
        parse_safe_range(args.safe_range)
    port = args.port or None
    real = port is not None and not port.startswith("xac1sim://")
    if args.allow_motion and real and args.safe_range is None:
        raise SettingsError("--allow-motion needs --safe-range LO:HI: the positions the actuator may be "
                            "moved to (e.g. --safe-range 0:0x1000)")
    if args.safe_range is not None and not args.allow_motion:
        raise SettingsError("--safe-range goes with --allow-motion (without it no move is ever sent)")
    return Settings.make(port, args.allow_motion, fresh=False, safe_range=args.safe_range,
                         timeout=args.timeout, restore_mode0=args.restore_mode0, cli=True)


def _check_paths(args: argparse.Namespace) -> str | None:
    from xac1_proto.output_file import OutputFileError, check_output

    try:
        for option, path in (("--report", args.report), ("--junit", args.junit)):
            if path:
                check_output(path, option)
    except OutputFileError as exc:
        return str(exc)
    if args.save:
        try:
            os.makedirs(args.save, exist_ok=True)
        except OSError as exc:
            return f"--save {args.save}: cannot make the folder: {exc.strerror or exc}"
        if not os.access(args.save, os.W_OK):
            return f"--save {args.save}: the folder is not writable"
    return None


def run(args: argparse.Namespace) -> int:
    from xac1_proto.dut.settings import SettingsError

    try:
        settings = _settings(args)
    except SettingsError as exc:
        return _error(str(exc))
    problem = _check_paths(args)
    if problem is not None:
        return _error(f"{problem}; nothing sent")
    seed = args.seed if args.seed is not None else int.from_bytes(os.urandom(4), "big")
    return _fuzz(args, settings, seed)


def _fuzz(args: argparse.Namespace, settings: Settings, seed: int) -> int:
    from serial import SerialException

    from xac1_proto.dut.device import DeviceAbort
    from xac1_proto.dut.safety import restore, take_snapshot
    from xac1_proto.fuzz.judge import Transcript
    from xac1_proto.history.model import now
    from xac1_proto.signals import EXIT_EARLY, Interrupted, OrderlyEnd

    from .fuzz_run import FuzzRun, Limits
    from .fuzz_unit import Unit, ask_on_terminal

    out = _Output(args, sys.stdout)
    began = now()  # for the history
    with OrderlyEnd(PROGRAM, "stopping the fuzz run: the unit is restored, then the summary follows") as end:
        try:
            transcript = Transcript(settings.timeout)
            ask = ask_on_terminal if sys.stdin.isatty() and sys.stderr.isatty() else None
            try:
                unit = Unit(settings, transcript, ask)
            except (OSError, ValueError, SerialException) as exc:
                return _error(f"cannot open {settings.port}: {exc}; nothing sent", EXIT_DEVICE)
            try:
                snap = take_snapshot(unit.dut)
                version = unit.version()
                if not version:
                    raise DeviceAbort("0RV got no answer")
            except DeviceAbort as exc:
                unit.close()
                return _error(f"cannot read the unit's points, OUT ports and version first: {exc}",
                              EXIT_DEVICE)
        except Interrupted as exc:
            print(f"{PROGRAM}: stopped by {exc.name} before the first case; nothing of the fuzz sent",
                  file=sys.stderr)
            return EXIT_EARLY
        end.begin()
        limits = Limits(args.cases if args.cases or args.seconds else DEFAULT_CASES, args.seconds,
                        args.state_every, args.max_findings, args.shrink_budget)
        clock_offset = time.time() - time.monotonic()
        started = time.monotonic()
        fuzz = FuzzRun(unit, snap, version, seed, limits, motion=args.allow_motion, on_case=out.case,
                       on_finding=lambda r, chunks: out.found(r, chunks, clock_offset, settings.port))
        failure = None
        with out.progress(limits) as bar:
            out.bar = bar
            try:
                fuzz.run(end.stop.is_set)
            except Exception as exc:  # noqa: BLE001 - a bug must not leave the unit changed: restore, say it
                failure = f"the run stopped: {type(exc).__name__}: {exc}"
        end.ending()
        restored = restore(unit.dut, snap)
        unit.close()
        seconds = time.monotonic() - started
    return _conclude(args, settings, seed, fuzz, restored, end.signal_name, failure, (began, seconds), out)


def _conclude(args: argparse.Namespace, settings: Settings, seed: int, fuzz: Any, restored: Any,
              signal: str | None, failure: str | None, when: tuple[_dt.datetime, float], out: _Output) -> int:
    """Print the summary and the restore, write the report and JUnit, record the run in the history;
    the exit status."""
    from xac1_proto.fuzz.judge import answers_in
    from xac1_proto.fuzz.results import RunSummary

    if signal is not None and not fuzz.results:
        status = EXIT_USAGE  # interrupted before a case
    else:
        status = EXIT_FINDINGS if fuzz.findings else EXIT_CLEAN
    version = next((getattr(f, "version", None) for f in answers_in(fuzz.version)), None)
    lines = restored.lines + restored.warnings + restored.problems
    if restored.unverified:  # what the restore's own log cannot know: what the cases may have written
        lines += [restored.unverified[0], *_changes_by_cases(fuzz)]
    began, seconds = when
    summary = RunSummary.of(fuzz.results, fuzz.findings, port=settings.port, seed=seed, seconds=seconds,
                            version=version, motion=args.allow_motion, interrupted=signal,
                            stopped=fuzz.stopped or failure, restore=tuple(lines), restored=restored.ok,
                            exit=status)
    out.summary(summary)
    for note in fuzz.refused:
        print(f"{PROGRAM}: a move left out (the motion guard refused it; nothing sent): {note}",
              file=sys.stderr)
    for line in lines:
        print(f"{PROGRAM}: restore: {line}", file=sys.stderr)
    from .fuzz_files import write_junit, write_report

    for option, path, write in (("--report", args.report, write_report),
                                ("--junit", args.junit, write_junit)):
        if path:
            try:
                write(path, summary)
            except OSError as exc:
                print(f"{PROGRAM}: cannot write {option} {path}: {exc.strerror or exc}", file=sys.stderr)
            else:
                print(f"{PROGRAM}: {option[2:]} written to {path}", file=sys.stderr)
    from .fuzz_history import record_fuzz

    record_fuzz(summary, args, settings, fuzz.limits, began, PROGRAM)
    return status


def _changes_by_cases(fuzz: Any) -> list[str]:
    """What the cases sent that a lenient controller may have carried out as a write, when the restore
    could not check it."""
    from xac1_proto import spec
    from xac1_proto.chunk import HOST
    from xac1_proto.codec import diagnose
    from xac1_proto.frames import StoreCurrent, SwitchMode, WriteOutputs, WritePoint

    sent = b"".join(c.data for c in fuzz.transcript.chunks if c.dir == HOST)
    points: set[int] = set()
    outputs = mode = False
    for line in sent.split(b"\n"):
        command, _ = diagnose(line.upper() + b"\n", spec.COMMAND)
        if isinstance(command, (WritePoint, StoreCurrent)):
            points.add(command.n)
        outputs = outputs or isinstance(command, WriteOutputs)
        mode = mode or isinstance(command, SwitchMode)
    out = [f"not verified: point {n:X}, which a case may have written" for n in sorted(points)]
    out += ["not verified: the OUT ports, which a case may have written"] if outputs else []
    out += ["not verified: the mode, which a case may have switched (0CM)"] if mode else []
    return out or ["no case sent a line a controller could take for a write or a mode switch"]


class _Output:
    """Results on stdout as text or JSON lines; the live progress bar on stderr (a terminal only)."""

    def __init__(self, args: argparse.Namespace, stream: TextIO) -> None:
        self.args = args
        self.stream = stream
        self.jsonl = args.format == "jsonl"
        self.bar: Any = None
        self.found_count = 0

    def progress(self, limits: Any) -> Any:
        from .fuzz_progress import ProgressBar

        return ProgressBar(limits.cases, limits.seconds, enabled=sys.stderr.isatty())

    def write(self, obj: dict[str, Any]) -> None:
        self.stream.write(json.dumps(obj) + "\n")
        self.stream.flush()

    def case(self, result: CaseResult) -> None:
        if self.jsonl:
            self.write(result.as_dict())
        if self.bar is not None:
            self.bar.advance(self.found_count + (result.finding is not None))

    def found(self, reported: Reported, chunks: list[Chunk], clock_offset: float, port: str) -> str | None:
        """Save the capture (``--save``) and show the finding; the capture's path."""
        from dataclasses import replace

        self.found_count += 1
        capture = None
        if self.args.save:
            from .fuzz_files import save_capture

            try:
                capture = save_capture(self.args.save, self.found_count, reported, chunks, clock_offset,
                                       f"xac1 fuzz --port {port}")
            except OSError as exc:
                print(f"{PROGRAM}: cannot save the capture in {self.args.save}: {exc.strerror or exc}",
                      file=sys.stderr)
        shown = replace(reported, capture=capture)
        if self.jsonl:
            self.write(shown.as_dict())
        else:
            self.stream.write(_finding_text(self.found_count, shown))
            self.stream.flush()
        return capture

    def summary(self, s: RunSummary) -> None:
        if self.jsonl:
            self.write(s.as_dict())
            return
        from xac1_proto.fuzz.results import outcome

        self.stream.write(f"{PROGRAM}: {s.cases} cases against {s.port} (seed {s.seed}, {s.seconds:.1f} s): "
                          f"{outcome(s)}\n")
        self.stream.flush()


def _finding_text(number: int, r: Reported) -> str:
    from xac1_proto.fuzz.results import wire

    f = r.finding
    how = (f"shrunk from {len(r.found)} write(s) in {r.tries} re-runs" if r.shrunk
           else f"not shrunk: {r.why}")
    lines = [f"finding {number}: {f.kind} (case {r.case}; {how})",
             *(f"  sent: {wire(x)}" for x in f.lines),
             f"  seen: {f.detail}",
             f"  codes: {', '.join(f.codes) or 'none'}"]
    if r.capture:
        lines.append(f"  capture: {r.capture} (replay it: xac1 replay {r.capture} --port URL)")
    return "\n".join(lines) + "\n"
