"""The front panel's view of the line: the simulator's bytes both ways judged by the one rulebook (sans-IO).

How it works: ``LineWatch.feed(t, direction, data)`` cuts each direction into frames and junk runs with
its own ``Framer`` and hands them, in the order seen, to one ``xac1_proto.conversation.Conversation``
(``host_frame``, ``device_frame``, ``host_junk``, ``device_junk``); ``tick(now)`` lets time pass so a
missed answer comes out as ``no-answer``. Facts the line cannot show come from the control channel:
``stop_input`` and ``power_on`` pass them to the engine. Every verdict becomes a row (``Row``: plain
data for the page, the bytes as typed, the decoded frame, and each violation with whose fault it is, its
severity, its docs/protocol.md meaning and the engine's sentence, as ``xac1 sniff`` names them). The
last ``keep`` verdicts are kept and made rows only when asked (``rows``). A view only: the rules, the
pairing and the sides are the engine's.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Final

from ... import spec
from ...codec import show_bytes
from ...conversation import Conversation, Verdict
from ...framer import FrameBytes, Framer, Junk

KEEP: Final = 40  # rows the panel keeps and shows

Row = dict[str, Any]


class LineWatch:
    """The simulator's line as the engine judges it; ``rows`` are the last ``keep`` verdicts."""

    def __init__(self, keep: int = KEEP) -> None:
        self.conversation = Conversation()
        self._framers = {spec.HOST_SIDE: Framer(), spec.DEVICE_SIDE: Framer()}
        self._kept: deque[tuple[int, Verdict]] = deque(maxlen=keep)
        self.seen = 0  # verdicts so far (the page asks for the rows after the last it has)

    def feed(self, t: float, direction: str, data: bytes) -> None:
        """Bytes ``direction`` ("host" or "device") put on the line, the last at ``t`` (unix seconds)."""
        framer = self._framers.get(direction)
        if framer is None:
            raise ValueError(f"direction must be 'host' or 'device', got {direction!r}")
        self._take(self.conversation.tick(t))
        host = direction == spec.HOST_SIDE
        c = self.conversation
        for event in framer.feed(data, t):
            if isinstance(event, FrameBytes):
                judge = c.host_frame if host else c.device_frame
                self._take(judge(event.raw, event.t_first, event.t_last))
            else:
                self._junk(host, event)

    def _junk(self, host: bool, event: Junk) -> None:
        c = self.conversation
        if host:
            self._take(c.host_junk(event.raw, event.t_first, event.t_last))
        else:
            self._take(c.device_junk(event.raw, event.t_first, event.t_last, event.reason == "flushed"))

    def tick(self, now: float) -> None:
        """Time passes to ``now``: answers that never came come out as ``no-answer`` rows."""
        self._take(self.conversation.tick(now))

    def stop_input(self, pressed: bool, unhomes: bool) -> None:
        """The emergency stop input changed (the control channel knows; the line cannot show it)."""
        self.conversation.stop_input(pressed, unhomes=unhomes)

    def power_on(self) -> None:
        """The unit was power-cycled: not homed, mode 0, nothing latched."""
        self.conversation.power_on()

    def _take(self, verdicts: list[Verdict]) -> None:
        for verdict in verdicts:
            self.seen += 1
            self._kept.append((self.seen, verdict))

    def rows(self, after: int = 0) -> list[Row]:
        """The kept verdicts numbered above ``after``, as rows, oldest first."""
        return [row_of(v, n) for n, v in self._kept if n > after]


def row_of(v: Verdict, number: int) -> Row:
    """One verdict as plain data for the page."""
    if v.frame is not None:
        decoded = str(v.frame)
        if v.header == spec.ALARM_HEADER:
            decoded += f" ({spec.alarm_meaning(v.frame.fields()['code'])})"
    elif v.kind == "no-answer":
        decoded = f"no answer to #{v.reply_to}"
    elif v.kind in ("host-junk", "device-junk"):
        decoded = "junk (bytes that form no frame)"
    else:
        decoded = f"{v.header or 'unknown'} (not decodable)"
    messages = [x.message for x in v.violations]
    violations = []
    for code, side in zip(v.codes, v.sides, strict=True):
        severity, meaning = spec.VIOLATIONS[code]
        suffix = f" ({code})"
        detail = "; ".join(m.removesuffix(suffix) for m in messages if m.endswith(suffix))
        violations.append({"code": code, "side": side, "severity": severity, "meaning": meaning,
                           "detail": detail})
    return {
        "n": number, "i": v.i, "kind": v.kind, "dir": v.sender, "t": v.t,
        "raw": show_bytes(v.raw) if v.raw else "", "decoded": decoded, "reply_to": v.reply_to,
        "latency_ms": None if v.latency_s is None else round(v.latency_s * 1000, 3),
        "violations": violations,
    }
