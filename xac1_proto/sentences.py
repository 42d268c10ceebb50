"""The sentences that explain the conversation's violations, made only where a violation is shown.

How this works: the engine (``conversation``) records a violation as its rule, code, severity, one of
the functions below and the few values it needs (``Violation.said``); the sentence is made when a view
reads ``Violation.message`` (the text view, JSON lines, reports), never on the way (``--format summary``
makes none). Each function is named after the rule it explains and returns the whole sentence: what
happened, the docs/protocol.md section and the code. ``made()`` counts the sentences made, so a test can
check that a path that shows no sentence makes none.
"""

from __future__ import annotations

from typing import Final

from . import spec
from .codec import show_bytes

BEHAVIOUR: Final = 'docs/protocol.md "Behaviour the vendor text states"'
CODES: Final = 'docs/protocol.md "Violation codes"'
FRAMING: Final = 'docs/protocol.md "Framing"'

_made = 0  # sentences made since the process started (``made``)


def made() -> int:
    """How many sentences have been made (every call of a function below counts one)."""
    return _made


def _said(text: str, where: str, code: str) -> str:
    global _made
    _made += 1
    return f"{text}; {where} ({code})"


def _name(header: str | None, i: int) -> str:
    return f"{header or 'line'} #{i}"


def garbage(side: str, raw: bytes) -> str:
    global _made
    _made += 1
    return f"{len(raw)} {side} bytes that form no frame: {show_bytes(raw)} (garbage)"


def unsolicited_answer(header: str | None) -> str:
    return _said(f"{header or 'this'} answer with no command waiting for it", CODES, "unsolicited-answer")


def command_during_motion(header: str | None, move_header: str | None, move_i: int) -> str:
    return _said(f"{header or 'this line'} sent while the move {_name(move_header, move_i)} waits for its "
                 f"answer", BEHAVIOUR, "command-during-motion")


def overlapping_command(header: str | None, first_header: str | None, first_i: int, untimed: bool) -> str:
    first = _name(first_header, first_i)
    detail = f"{header or 'this line'} sent before the answer to {first}"
    if untimed:
        detail += (f"; the capture has no time, so this looks the same as {first} left unanswered and the "
                   f"host going on after waiting (no-answer)")
    return _said(detail, FRAMING, "overlapping-command")


def no_answer(header: str | None, i: int, error: bool, skipped_by: int | None, waited_s: float | None) -> str:
    """``skipped_by``: the later line the device answered instead; ``waited_s``: the window that closed
    (None: the data ended first)."""
    owed = "an alarm answer (an error must be answered with one)" if error else "its answer"
    if skipped_by is not None:
        when = f"the device answered a later line instead (#{skipped_by})"
    elif waited_s is None:
        when = "the data ended first"
    else:
        when = f"nothing came within {waited_s:.3f} s of its last byte"
    return _said(f"{_name(header, i)} got no answer: it is owed {owed}, but {when}", BEHAVIOUR, "no-answer")


def storm_recovery(header: str | None, run: int, reset: bool) -> str:
    which = "an alarm reset" if reset else "the first command after a successful alarm reset"
    return _said(f"{header or 'this frame'}, {which}, sent after {run} communication-error answers (0%%01) "
                 f"in a row: recovering, which the vendor text does not forbid", BEHAVIOUR, "storm-recovery")


def comm_error_storm(header: str | None, run: int, limit: int) -> str:
    return _said(f"{header or 'this frame'} sent after {run} communication-error answers (0%%01) in a row; "
                 f"the host must stop after {limit}", BEHAVIOUR, "comm-error-storm")


def alarm_ignored(header: str | None) -> str:
    return _said(f"{header or 'this frame'} sent after an alarm answer without an alarm reset (0%C)",
                 BEHAVIOUR, "alarm-ignored")


def error_accepted(header: str, line_header: str | None, i: int) -> str:
    return _said(f"{header} answer to {_name(line_header, i)}, which breaks the frame table: an error is "
                 f"answered with an alarm answer (0%%Ec)", BEHAVIOUR, "error-accepted")


def reset_refused(header: str | None, i: int, code: int) -> str:
    return _said(f"the alarm reset {_name(header, i)} was answered with alarm {code:02X}: 0%C clears every "
                 f"alarm but emergency stop (0E) and answers 0%C00", BEHAVIOUR, "latch-broken")


def cleared_alarm_back(header: str | None, i: int, code: int) -> str:
    return _said(f"alarm {code:02X} answers {_name(header, i)} after the emergency stop, but the alarm reset "
                 f"during the stop cleared it: 0%C clears every alarm but emergency stop (0E)", BEHAVIOUR,
                 "latch-broken")


def held_alarm_lost(header: str | None, under: int) -> str:
    return _said(f"{header} got a normal answer after the emergency stop, but alarm {under:02X} was latched "
                 f"before it and no reset cleared it", BEHAVIOUR, "latch-broken")


def latch_code_changed(latched: int, code: int) -> str:
    return _said(f"alarm {latched:02X} is latched, but the answer is alarm {code:02X}: a latched alarm is "
                 f"repeated until a reset", BEHAVIOUR, "latch-broken")


def latch_broken(header: str | None, latched: int) -> str:
    return _said(f"{header} got a normal answer while alarm {latched:02X} ({spec.alarm_meaning(latched)}) "
                 f"should still be latched", BEHAVIOUR, "latch-broken")


def estop_cleared() -> str:
    return _said("the alarm reset answered 0%C00 while the emergency stop input is pressed: emergency stop "
                 "(0E) stays latched until the input is released", BEHAVIOUR, "estop-cleared")


def answer_mismatch(header: str, line_header: str | None, i: int) -> str:
    return _said(f"{header} answer to the {_name(line_header, i)} command", CODES, "answer-mismatch")


def answer_for_other_n(header: str, n: int, line_header: str | None, i: int, sent_n: int) -> str:
    return _said(f"{header} answer for N={n:X} to the command {_name(line_header, i)} for N={sent_n:X}",
                 CODES, "answer-mismatch")


def _show(name: str, value: object) -> str:
    return spec.FIELDS[name].show(value) if isinstance(value, int) else str(value)


def echo_mismatch(header: str, line_header: str | None, i: int, echo: object, command: object) -> str:
    """``echo`` and ``command``: the two frames (``Frame.fields``)."""
    mine, theirs = echo.fields(), command.fields()  # type: ignore[attr-defined]
    diff = ", ".join(f"{spec.FIELDS[k].label} {_show(k, v)} (sent {_show(k, theirs.get(k))})"
                     for k, v in mine.items() if theirs.get(k) != v)
    return _said(f"{header} echo differs from the command {_name(line_header, i)}: {diff}", BEHAVIOUR,
                 "echo-mismatch")


def readback(what: str, seen: object, established: bool, how: str) -> str:
    how_known = "established" if established else "read earlier"
    return _said(f"{what} reads back {seen}, but the conversation {how_known} {how}", BEHAVIOUR,
                 "readback-mismatch")


def late_move_answer(header: str | None, i: int, latency_s: float | None, window_s: float) -> str:
    came = "" if latency_s is None else f" {latency_s:.3f} s after its last byte"
    return _said(f"the answer to {_name(header, i)} came{came}, later than its {window_s:.3f} s window, "
                 f"which rests on the guessed speed table (give the device's with --speed-table)",
                 'docs/protocol.md "Where the vendor text is silent", items 15 and 17', "no-answer")
