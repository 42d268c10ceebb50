"""The simulator's send queue: answer bytes with the time each is due, line faults applied (sans-IO).

The device model puts each answer in the outbox with the time its first byte is due; with wire timing
every later byte is due one byte time (1.0417 ms, docs/protocol.md "Line") after the one before, and an
answer never starts before the previous one has gone out. Line faults are applied as an answer enters
the queue, from a ``random.Random`` seeded by ``LineFaults.seed`` (so a seed replays the same spoiling
for the same conversation). A shell asks ``next_due`` for when to wake up and ``pop(t)`` for the bytes
due by ``t``; ``cancel()`` drops what has not gone out (an emergency stop during a move).
"""

from __future__ import annotations

import random
from collections import deque
from dataclasses import dataclass

from .. import spec
from .config import LineFaults


@dataclass(frozen=True, slots=True)
class Output:
    """One answer as scheduled: its bytes (after line faults), when the first byte is due, and the
    time between bytes (0 without wire timing)."""

    data: bytes
    due: float
    byte_time: float = 0.0

    @property
    def end(self) -> float:
        return self.due + self.byte_time * len(self.data)


class Outbox:
    """Answers waiting to go out, in order."""

    def __init__(self, faults: LineFaults | None = None) -> None:
        self._queue: deque[tuple[Output, int]] = deque()  # (output, bytes already popped)
        self._last_end = float("-inf")
        self.set_faults(faults or LineFaults())

    def set_faults(self, faults: LineFaults) -> None:
        self.faults = faults
        self._rng = random.Random(faults.seed)

    def put(self, data: bytes, due: float, wire_timing: bool = False) -> Output:
        """Queue an answer; returns it as scheduled (line faults applied)."""
        f = self.faults
        if f.active:
            if f.delay and self._rng.random() < f.delay:
                due += f.delay_s
            out = bytearray()
            for b in data:
                if f.drop and self._rng.random() < f.drop:
                    continue
                if f.corrupt and self._rng.random() < f.corrupt:
                    b ^= 1 << self._rng.randrange(8)
                out.append(b)
            data = bytes(out)
        byte_time = spec.BYTE_TIME_S if wire_timing else 0.0
        output = Output(data, max(due, self._last_end), byte_time)
        self._last_end = output.end
        if data:
            self._queue.append((output, 0))
        return output

    @property
    def next_due(self) -> float | None:
        """When the next byte is due, or None when nothing waits."""
        if not self._queue:
            return None
        output, sent = self._queue[0]
        return output.due + output.byte_time * sent

    def pop(self, t: float) -> bytes:
        """The bytes due by ``t``, removed from the queue."""
        got = bytearray()
        while self._queue:
            output, sent = self._queue[0]
            if output.byte_time:
                ready = min(len(output.data), int((t - output.due) / output.byte_time) + 1) \
                    if t >= output.due else 0
            else:
                ready = len(output.data) if t >= output.due else 0
            if ready <= sent:
                break
            got += output.data[sent:ready]
            if ready < len(output.data):
                self._queue[0] = (output, ready)
                break
            self._queue.popleft()
        return bytes(got)

    def cancel(self) -> None:
        """Drop everything not yet sent."""
        self._queue.clear()
        self._last_end = float("-inf")

    def __len__(self) -> int:
        return len(self._queue)
