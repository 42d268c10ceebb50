"""``xac1 replay``: play a capture's host side against a device and show where its answers differ.

A thin shell: the capture is read as ``xac1 decode`` reads it (``sniffer.replay_script``), the options
are checked before anything is sent, the device's points, OUT ports and position are read first and put
back at the end however the run ends (``xac1_proto.dut.safety``: the conformance suite's snapshot and
restore; SIGINT, SIGTERM and SIGHUP end the replay in order, ``xac1_proto.signals``), the lines are
played by ``sniffer.replay_player`` under the motion guard (``sniffer.replay_guard``), and the results
are printed (``--format text``/``jsonl``) and, with ``--report``, written as a page
(``sniffer.replay_report``).

Exit status: 0 every captured host line replayed and every answer the same; 1 some differ, or a line
was skipped, or a signal ended the replay early; 2 bad options or capture (nothing sent); 3 the device
could not be reached or stopped answering.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final, TextIO

from xac1_proto import rules

from .capture_args import add_capture_arguments

if TYPE_CHECKING:
    import datetime as _dt

    from xac1_proto.dut.safety import RestoreReport, Snapshot
    from xac1_proto.dut.settings import Settings
    from xac1_proto.replay import Answer, Script

    from .io.base import Report
    from .replay_player import LineResult

HELP = "play a capture's host side against a controller (or the simulator) and show where the answers differ"
PROGRAM: Final = "xac1 replay"
EXIT_SAME, EXIT_DIFFERENT, EXIT_USAGE, EXIT_DEVICE = 0, 1, 2, 3


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value) or value <= 0 or value > 3600:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number of seconds above 0 and at most 3600")
    return value


def add_arguments(p: argparse.ArgumentParser) -> None:
    from .replay_player import PACES

    add_capture_arguments(p)
    p.add_argument("--port", metavar="URL", default=None,
                   help="the device: a serial port path or any pyserial URL (socket://HOST:PORT, "
                        "xac1sim://?time_scale=0); not needed with --dry-run")
    p.add_argument("--pace", choices=PACES, default="captured",
                   help="captured (default): the gaps of the capture, overlaps kept; fast: only wait for "
                        "each answer (back-to-back lines still overlap)")
    p.add_argument("--format", "-f", choices=("text", "jsonl"), default="text",
                   help="a line per replayed host line (text, default) or JSON lines")
    p.add_argument("--report", metavar="FILE.html", default=None,
                   help="also write a side-by-side page (captured vs now)")
    p.add_argument("--readings", choices=rules.READINGS, default=rules.DEFAULT_READINGS,
                   help=rules.READINGS_HELP)
    p.add_argument("--allow-motion", action="store_true",
                   help="send the capture's moves (0MP, 0MV) to a real device; needs --safe-range")
    p.add_argument("--safe-range", metavar="LO:HI", default=None,
                   help="positions the actuator may be moved to (decimal or 0x-hex, e.g. 0:0x1000); a move "
                        "outside is not sent (shown as skipped)")
    p.add_argument("--restore-mode0", action="store_true",
                   help="send 0CM0 as the very last command (external start inputs enabled again)")
    p.add_argument("--dry-run", action="store_true",
                   help="show what would be sent (and skipped); open no port, send nothing")
    p.add_argument("--timeout", type=_seconds, metavar="S", default=None,
                   help="no-answer timeout after a line's last byte (moves' estimated time doubled on "
                        "top), for reading the capture and judging the new conversation, as xac1 decode "
                        "--timeout (default 1; the new conversation with xac1sim://: 0.2)")
    p.add_argument("--color", action=argparse.BooleanOptionalAction, default=None,
                   help="colour in the text output (default: when the output is a terminal)")
    from xac1_proto.history.command import add_arguments as history_arguments

    history_arguments(p, "the replay")


def _error(message: str, status: int = EXIT_USAGE) -> int:
    print(f"{PROGRAM}: {message}", file=sys.stderr)
    return status


def _settings(args: argparse.Namespace) -> Settings:
    """The conformance suite's settings for this run; SettingsError for a bad combination."""
    from xac1_proto.dut.settings import Settings, SettingsError, parse_safe_range

    if args.safe_range is not None:
        parse_safe_range(args.safe_range)  # a bad range is said before anything else
    if args.allow_motion and args.safe_range is None:
        raise SettingsError("--allow-motion needs --safe-range LO:HI: the positions the actuator may be "
                            "moved to (e.g. --safe-range 0:0x1000)")
    port = args.port or "(no port: dry run)"  # judged as a real device: moves only when allowed
    return Settings.make(port, args.allow_motion, fresh=False, safe_range=args.safe_range,
                         timeout=args.timeout, restore_mode0=args.restore_mode0, cli=True)


def run(args: argparse.Namespace) -> int:
    from xac1_proto.dut.settings import SettingsError

    from .replay_script import CaptureError, read_script

    if args.port is None and not args.dry_run:
        return _error("give the device with --port URL (or --dry-run to see what would be sent)")
    try:
        settings = _settings(args)
    except SettingsError as exc:
        return _error(exc.in_cli_words())
    if args.report is not None:
        from xac1_proto.output_file import OutputFileError, check_output

        try:  # a report path that cannot take the page is known before anything is sent
            check_output(args.report, "--report")
        except OutputFileError as exc:
            return _error(f"{exc}; nothing sent")
    if args.dry_run:
        return _dry_run(args, settings)
    try:
        captured = read_script(args.files, args.input_format, args.host_is, args.samplerate, PROGRAM,
                               args.timeout)
    except CaptureError as exc:
        return _error(f"{exc}; nothing sent")
    _say_problems(captured.report, captured.format, "the rest is replayed")
    return _replay(args, settings, captured.script, captured.format)


def _say_problems(report: Report, fmt: str, rest: str) -> None:
    for note in report.notes:
        print(f"{PROGRAM}: note: {note}", file=sys.stderr)
    if report.total_problems:
        print(f"{PROGRAM}: {fmt}: {report.summary()}; {rest}", file=sys.stderr)


# ---- dry run ----

def _dry_run(args: argparse.Namespace, settings: Settings) -> int:
    """Each line as it would go, the guard asked with what the capture itself establishes; the capture
    is read line by line (``ScriptStream``), so a capture of any size takes flat memory. Its notes and
    problems follow the lines (they are known once it has been read)."""
    from xac1_proto.chunk import DEVICE, HOST, Chunk

    from .analyzer import Analyzer
    from .replay_guard import MotionGuard
    from .replay_script import CaptureError, ScriptStream

    analyzer = Analyzer(readings=args.readings)
    guard = MotionGuard(settings, lambda: analyzer.conversation.knowledge)
    out = _Output(args, sys.stdout)
    skipped = 0
    try:
        with ScriptStream(args.files, args.input_format, args.host_is, args.samplerate, PROGRAM,
                          args.timeout) as stream:
            for line in stream:
                why = guard.check(line.raw)
                skipped += why is not None
                out.would(line, why)
                analyzer.feed(Chunk(line.t, HOST, line.raw))
                for answer, _ in line.replies:  # in the order they came
                    analyzer.feed(Chunk(answer.t, DEVICE, answer.raw))
    except CaptureError as exc:
        return _error(f"{exc}; nothing sent")
    _say_problems(stream.report, stream.format, "the rest was read")
    out.write({"type": "summary", "dry_run": True, "lines": stream.count,
               "would_send": stream.count - skipped, "skipped": skipped})
    return EXIT_SAME


# ---- the replay ----

def _replay(args: argparse.Namespace, settings: Settings, script: Script, fmt: str) -> int:
    from xac1_proto.client import Client, open_port
    from xac1_proto.dut.device import DeviceAbort, DeviceUnderTest
    from xac1_proto.dut.safety import restore, take_snapshot
    from xac1_proto.history.model import now
    from xac1_proto.signals import EXIT_EARLY, Interrupted, OrderlyEnd

    from .analyzer import Analyzer
    from .replay_guard import MotionGuard
    from .replay_player import Player, PortFailed

    started = now()
    with OrderlyEnd(PROGRAM, "stopping the replay: the device is restored, then the results follow") as end:
        opened = False
        try:
            try:
                port, _ = open_port(settings.port)
                opened = True
            except (OSError, ValueError) as exc:  # serial.SerialException is an OSError
                return _error(f"cannot open {settings.port}: {exc}; nothing sent", EXIT_DEVICE)
            try:
                dut = DeviceUnderTest(settings, Client(port, timeout=settings.timeout,
                                                       time_scale=settings.time_scale))
                snap = take_snapshot(dut)
            except DeviceAbort as exc:
                port.close()
                return _error(f"cannot read the device's points, OUT ports and position first: {exc}",
                              EXIT_DEVICE)
            end.begin()  # a signal that came before is raised here
        except Interrupted as exc:
            print(f"{PROGRAM}: stopped by {exc.name} before the replay began; nothing of the capture sent",
                  file=sys.stderr)
            if opened:  # the snapshot only read: nothing to put back
                port.close()
            return EXIT_EARLY
        analyzer = Analyzer(no_answer_timeout=settings.timeout, readings=args.readings)
        guard = MotionGuard(settings, lambda: analyzer.conversation.knowledge,
                            {n: p.pos for n, p in snap.points.items()}, homed=snap.position is not None)
        out = _Output(args, sys.stdout)
        player = Player(port, script, analyzer, pace=args.pace, check=guard.check, alive=lambda: _alive(dut),
                        stop=end.stop, on_result=out.result)
        failure: str | None = None
        port_failed = False
        try:
            player.run()
        except PortFailed as exc:  # nothing more can be sent: no restore
            failure, port_failed = str(exc), True
            player.close()
        except Exception as exc:  # noqa: BLE001 - a bug must not leave the device changed: restore, say it
            failure = f"the replay stopped: {type(exc).__name__}: {exc}"
        end.ending()
        restored = None if port_failed else restore(dut, snap)
        port.close()
        outcome = Outcome(player.played, _restore_lines(restored, player.played, snap),
                          None if restored is None else restored.ok, player.stopped or port_failed, failure,
                          end.signal_name, started, dut.version)
        return _conclude(args, script, fmt, outcome, out)  # still under the policy: a signal is ignored


@dataclass(frozen=True)
class Outcome:
    """How a replay went: the lines played, what the restore did (``restored``: verified; None: not
    done), whether the device stopped answering (or the port failed), why it stopped early (``failure``),
    the signal that ended it."""

    results: list[LineResult]
    restore: list[str]
    restored: bool | None
    stopped: bool
    failure: str | None
    signal: str | None
    started: _dt.datetime  # for the history
    firmware: str | None  # what 0RV answered (the history)


def _restore_lines(restored: RestoreReport | None, results: list[LineResult], snap: Snapshot) -> list[str]:
    """What the restore did; where it could not be done or verified, what the replay sent that may have
    changed the device, with the values it had before."""
    if restored is None:
        return ["not done (the port failed)", *_changes_by_replay(results, snap)]
    lines = restored.lines + restored.warnings + restored.problems
    if restored.unverified:
        lines += [restored.unverified[0], *_changes_by_replay(results, snap)]
    return lines


def _changes_by_replay(results: list[LineResult], snap: Snapshot) -> list[str]:
    from xac1_proto import spec
    from xac1_proto.codec import diagnose
    from xac1_proto.frames import MoveDirect, MovePoint, StoreCurrent, SwitchMode, WriteOutputs, WritePoint

    points: set[int] = set()
    outputs = moved = mode = False
    for r in results:
        if r.t_sent is None:
            continue
        command, _ = diagnose(r.line.raw, spec.COMMAND)  # a sloppy line a device may still carry out
        if isinstance(command, (WritePoint, StoreCurrent)) and command.n in snap.points:
            points.add(command.n)
        outputs = outputs or isinstance(command, WriteOutputs)
        moved = moved or isinstance(command, (MovePoint, MoveDirect))
        mode = mode or isinstance(command, SwitchMode)
    out = [f"not verified: point {n:X}, written by the replay; it held {snap.points[n].show()} before"
           for n in sorted(points)]
    if outputs:
        out.append(f"not verified: the OUT ports, written by the replay; they were {snap.outputs} before")
    if moved:
        out.append(f"not verified: the axis position, moved by the replay; 0RC read {snap.position_seen} "
                   f"before")
    if mode:
        out.append("not verified: the mode, switched by the replay (0CM)")
    return out or ["the replay sent nothing that changes the device (no write, no move, no 0CM)"]


def _alive(dut: Any) -> bool:
    """Does the device still answer (0RV, asked through the conformance suite's choke point)?"""
    from xac1_proto.dut.device import DeviceAbort
    from xac1_proto.frames import ReadVersion

    try:
        for _ in range(2):
            if not dut.send(ReadVersion()).silent:
                return True
    except DeviceAbort:
        return False
    return False


def _conclude(args: argparse.Namespace, script: Script, fmt: str, outcome: Outcome, out: _Output) -> int:
    """Print the summary (the lines went out as they were played) and what the restore did; write the
    page; the exit status."""
    results = outcome.results
    summary = _summary(results, len(script.lines))
    summary.update(stopped=outcome.stopped, interrupted=outcome.signal, restored=outcome.restored)
    every = summary["same"] == len(script.lines)  # every line replayed (none skipped, none left) and same
    status = EXIT_DEVICE if outcome.stopped else EXIT_SAME if every else EXIT_DIFFERENT
    summary["exit"] = status
    out.write(summary)
    if outcome.failure is not None:
        print(f"{PROGRAM}: {outcome.failure}", file=sys.stderr)
    elif outcome.stopped:
        from .replay_player import STOPPED_LIMIT

        print(f"{PROGRAM}: the device stopped answering: {summary['replayed']} lines sent, the last "
              f"{STOPPED_LIMIT} answered in the capture got not a byte back, nor did 0RV", file=sys.stderr)
    for line in outcome.restore:
        print(f"{PROGRAM}: restore: {line}", file=sys.stderr)
    if args.report is not None:
        from .replay_report import write_report

        try:
            written = write_report(args.report, args.files, fmt, results, summary, outcome.restore)
        except OSError as exc:
            print(f"{PROGRAM}: cannot write the report {args.report}: {exc.strerror or exc}",
                  file=sys.stderr)
        else:
            print(f"{PROGRAM}: report written to {written}", file=sys.stderr)
    from .replay_history import record_replay

    record_replay(args, outcome.started, outcome.firmware, results, summary, status, outcome.signal, PROGRAM)
    return status


def _summary(results: list[LineResult], total: int) -> dict[str, Any]:
    from collections import Counter

    from xac1_proto.replay import EXTRA, MISSING

    sent = [r for r in results if r.skipped is None]
    kinds: Counter[str] = Counter(d for r in sent for d in r.comparison.differences)
    codes: Counter[str] = Counter(c for r in sent for c in r.violations)
    return {"type": "summary", "lines": total, "replayed": len(sent),
            "same": sum(1 for r in sent if r.same), "different": sum(1 for r in sent if not r.same),
            "skipped": len(results) - len(sent), "missing": kinds.get(MISSING, 0),
            "extra": kinds.get(EXTRA, 0), "differences": dict(kinds), "violations": dict(codes)}


# ---- output ----

def text(data: bytes | None) -> str | None:
    """Bytes as JSON text (latin-1: every byte one character; JSON escapes CR and LF)."""
    return None if data is None else data.decode("latin-1")


def _joined(answers: list[Answer] | tuple[Answer, ...]) -> bytes | None:
    return b"".join(a.raw for a in answers) if answers else None


class _Output:
    """Text or JSON lines on ``stream``."""

    def __init__(self, args: argparse.Namespace, stream: TextIO) -> None:
        self.jsonl = args.format == "jsonl"
        self.stream = stream
        self.color = stream.isatty() if args.color is None else args.color

    def _paint(self, s: str, code: str) -> str:
        return f"\x1b[{code}m{s}\x1b[0m" if self.color else s

    def write(self, obj: dict[str, Any]) -> None:
        if self.jsonl:
            print(json.dumps(obj), file=self.stream, flush=True)
        elif obj.get("type") == "summary":
            print(_summary_text(obj), file=self.stream, flush=True)

    def would(self, line: Any, why: str | None) -> None:
        if self.jsonl:
            self.write({"type": "dry-run", "i": line.i, "sent": None if why else text(line.raw),
                        "line": text(line.raw), "skipped": why})
            return
        show = _show(line.raw)
        verdict = self._paint(f"skipped: {why}", "33") if why else "would send"
        print(f"{line.i:>5} {show:<24} {verdict}", file=self.stream)

    def result(self, r: LineResult) -> None:
        line = r.line
        if self.jsonl:
            obj: dict[str, Any] = {"type": "replay", "i": line.i,
                                   "sent": None if r.skipped else text(line.raw),
                                   "expected": text(_joined(line.answers)), "got": text(_joined(r.got)),
                                   "same": r.same, "differences": ["skipped"] if r.skipped
                                   else list(r.comparison.differences),
                                   "violations": list(dict.fromkeys(r.violations))}
            if r.skipped:
                obj["skipped"] = r.skipped
            self.write(obj)
            return
        sent = _show(line.raw)
        if r.skipped:
            print(f"{line.i:>5} {sent:<24} {self._paint('skipped: ' + r.skipped, '33')}", file=self.stream)
            return
        expected = _show(_joined(line.answers)) if line.answers else "(silence)"
        got = _show(_joined(r.got)) if r.got else "(silence)"
        verdict = self._paint("same", "32") if r.same else \
            self._paint("DIFFERENT: " + ", ".join(r.comparison.differences), "1;31")
        codes = list(dict.fromkeys(r.violations))
        tail = f"  [{', '.join(codes)}]" if codes else ""
        print(f"{line.i:>5} {sent:<24} captured {expected:<24} now {got:<24} {verdict}{tail}",
              file=self.stream)


def _show(data: bytes | None) -> str:
    from xac1_proto.codec import show_bytes

    return "" if data is None else show_bytes(data)


def _summary_text(s: dict[str, Any]) -> str:
    if s.get("dry_run"):
        return f"dry run: {s['lines']} host lines, {s['would_send']} would be sent, {s['skipped']} skipped"
    kinds = ", ".join(f"{k} {n}" for k, n in s["differences"].items())
    codes = ", ".join(f"{k} {n}" for k, n in s["violations"].items())
    parts = [f"replayed {s['replayed']} of {s['lines']} host lines: {s['same']} same, "
             f"{s['different']} different{f' ({kinds})' if kinds else ''}, {s['skipped']} skipped"]
    parts.append(f"violations now: {codes or 'none'}")
    if s.get("interrupted"):
        parts.append(f"stopped by {s['interrupted']}")
    if s.get("stopped"):
        parts.append("the device stopped answering")
    if s.get("restored") is not None:
        parts.append(f"device restored: {'yes' if s['restored'] else 'NOT fully (see above)'}")
    return "; ".join(parts)
