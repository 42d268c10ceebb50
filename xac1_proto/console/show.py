"""How an exchange reads on a terminal: both directions as bytes, the answer decoded, its latency,
alarms with their meaning, every violation named. Shared by ``xac1 send`` and ``xac1 console``."""

from __future__ import annotations

import os
import re

from ..codec import diagnose, show_bytes
from ..errors import AlarmError, CommunicationHalted, ProtocolError, ResponseTimeout
from ..exchange import Exchange
from ..spec import FRAME_END, NOTICES, TERMINATOR

_ESCAPES = {"r": b"\r", "n": b"\n", "\\": b"\\"}
_ESCAPE_HELP = "escapes: \\r \\n \\xNN, \\\\ for a backslash"


def command_bytes(text: str) -> bytes:
    """The bytes a user means by ``0RP3`` or ``0RP3\\r\\n`` (escapes \\r \\n \\xNN \\\\); CR LF is
    added when the text does not end with LF. Raises ValueError saying what is wrong and where."""
    out = bytearray()
    i = 0
    while i < len(text):
        ch = text[i]
        if ch == "\\":
            code = text[i + 1:i + 2]
            if code in _ESCAPES:
                out += _ESCAPES[code]
                i += 2
                continue
            digits = text[i + 2:i + 4]
            if code == "x" and re.fullmatch(r"[0-9A-Fa-f]{2}", digits):
                out.append(int(digits, 16))
                i += 4
                continue
            seen = text[i:i + 4] if code == "x" else text[i:i + 2]
            raise ValueError(f"bad escape {seen} at character {i + 1} of {text} ({_ESCAPE_HELP})")
        if not ch.isascii():
            raise ValueError(f"character {ch} at {i + 1} of {text} is not ASCII (write bytes as \\xNN)")
        out += ch.encode("ascii")
        i += 1
    if not out:
        raise ValueError("empty command; give a frame such as 0RV or 0RP3")
    data = bytes(out)
    return data if data.endswith(FRAME_END) else data + TERMINATOR


def port_problem(exc: BaseException) -> str:
    """What went wrong with a port, in the operating system's words, once: pyserial wraps the OS error
    in its own message (``could not open port X: [Errno 2] ...``); the OS error is what people need."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, OSError) and isinstance(seen.errno, int) and seen.errno > 0:
            return os.strerror(seen.errno)
        seen = seen.__cause__ or seen.__context__
    text = re.sub(r"\[Errno \d+\] ", "", str(exc))
    return re.sub(r"^(?i:could not open port) [^:]*: ", "", text) or type(exc).__name__


def sent_lines(raw: bytes) -> list[str]:
    """The command side: its bytes, decoded; a malformed command says how (what a probe meant to send)."""
    frame, violations = diagnose(raw, "command")
    broken = sorted({v.code for v in violations if v.code not in NOTICES})
    if not broken and frame is not None:
        return [f"> {show_bytes(raw)}   {frame}"]
    read_as = f"; read as {frame}" if frame is not None else ""
    return [f"> {show_bytes(raw)}   (malformed command: {', '.join(broken)}{read_as})"]


def answer_lines(ex: Exchange) -> list[str]:
    """The answer side of an exchange, one string a line."""
    out = []
    if ex.stale:
        out.append(f"  (discarded {len(ex.stale)} stale byte(s) waiting before the command: "
                   f"{show_bytes(ex.stale)})")
    latency = f"   [{ex.latency * 1000:.1f} ms]" if ex.latency is not None else ""
    out.append(f"< {show_bytes(ex.raw)}{latency}")
    if ex.frame is not None:
        out.append(f"  {ex.frame}")
    alarm = ex.alarm
    if alarm is not None:
        out.append(f"  ALARM {alarm.code:02X}: {alarm.meaning}")
    for v in ex.violations:
        kind = "notice" if v not in ex.errors else "PROTOCOL ERROR"
        out.append(f"  {kind}: {v.message}")
    return out


def error_line(exc: Exception) -> str:
    """One line for an error the client raised (the exchange's own lines say the rest)."""
    if isinstance(exc, ResponseTimeout):
        return f"timeout: {exc}"
    if isinstance(exc, CommunicationHalted):
        return f"halted: {exc}"
    if isinstance(exc, AlarmError):
        return f"alarm {exc.code:02X}: {exc.meaning}"
    if isinstance(exc, ProtocolError):
        return f"protocol error ({exc.code}): {exc}"
    return f"error: {exc}"
