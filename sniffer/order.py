"""Put the two taps' chunks back in cause-and-effect order (sans-IO; time passed in).

Two taps are two ports: each has its own delivery delay (a USB adapter's latency timer, a pty's
buffer push), so a command read on the host tap can come out after the answer read on the device tap.
An answer can only follow its command, so a chunk that would look out of order is held for up to
``window`` seconds: device bytes while nothing at all waits for an answer (they would be unsolicited),
host bytes while a command waits (they would overlap, or come during a move) or while a malformed
line sent less than ``window`` ago waits (its alarm answer may still be on the way). Whenever the other tap
delivers, that goes first and the held chunks follow as soon as they no longer look out of order; when
the window passes they go out as they are. When one poll reads both taps (a sniffer that fell behind
finds several exchanges waiting on each), both sides are cut into lines and merged: an answer goes
first whenever something waits for it, else the next host line. A true overlap closer than ``window``
(or than one poll) to its answer is then not seen: the sniffer prefers missing one to inventing one.
Times only move forward.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable

from xac1_proto.chunk import DEVICE, HOST, Chunk, Direction

REORDER_WINDOW_S = 0.1


class CausalOrder:
    """Chunks in via ``push(chunk, now)``; out, in order, through ``sink``. ``waiting()``: something the
    host sent waits for an answer; ``expecting()``: a command waits for its answer (both asked of the
    analyzer after each chunk is fed). Call ``due(now)`` now and then, ``flush()`` at the end."""

    def __init__(self, sink: Callable[[Chunk], None], waiting: Callable[[], bool],
                 expecting: Callable[[], bool], window: float = REORDER_WINDOW_S) -> None:
        self.sink = sink
        self.waiting = waiting
        self.expecting = expecting
        self.window = window
        self._held: list[Chunk] = []
        self._since = 0.0
        self._last_t: float | None = None
        self._host_out = float("-inf")

    def _out(self, chunk: Chunk, now: float) -> None:
        if chunk.dir == HOST:
            self._host_out = now
        if chunk.t is not None and self._last_t is not None and chunk.t < self._last_t:
            chunk = Chunk(self._last_t, chunk.dir, chunk.data, chunk.error)
        if chunk.t is not None:
            self._last_t = chunk.t
        self.sink(chunk)

    def _suspicious(self, chunk: Chunk, now: float) -> bool:
        if chunk.dir == HOST:  # a malformed line may still draw an answer just after it went out
            return self.expecting() or (self.waiting() and now - self._host_out < self.window)
        return not self.waiting()

    def push(self, chunk: Chunk, now: float) -> None:
        """A chunk just read. Device chunks are cut after each LF, so each answer is placed on its own;
        host chunks stay whole (commands read together, with no answer read beside them, were sent
        before any answer to them was read)."""
        for piece in (_lines(chunk) if chunk.dir != HOST else [chunk]):
            self._push(piece, now)

    def push_poll(self, chunks: Iterable[Chunk], now: float) -> None:
        """The chunks one poll read, in the order read; see the module docstring."""
        chunks = list(chunks)
        if len({c.dir for c in chunks}) < 2:
            for chunk in chunks:
                self.push(chunk, now)
            return
        lines: dict[Direction, deque[Chunk]] = {HOST: deque(), DEVICE: deque()}
        for chunk in self._held + chunks:  # what was held came first
            lines[chunk.dir].extend(_lines(chunk))
        self._held = []
        while lines[HOST] and lines[DEVICE]:
            side: Direction = DEVICE if not self._suspicious(lines[DEVICE][0], now) else HOST
            self._out(lines[side].popleft(), now)
        for rest in lines.values():
            for chunk in rest:
                self._push(chunk, now)

    def _push(self, chunk: Chunk, now: float) -> None:
        if self._held and chunk.dir == self._held[0].dir:
            self._held.append(chunk)
            return
        if not self._held and self._suspicious(chunk, now):
            self._held, self._since = [chunk], now
            return
        self._out(chunk, now)
        while self._held and not self._suspicious(self._held[0], now):
            self._out(self._held.pop(0), now)

    def due(self, now: float) -> None:
        """Held chunks whose window has passed go out."""
        if self._held and now - self._since >= self.window:
            self.flush(now)

    def flush(self, now: float = float("inf")) -> None:
        held, self._held = self._held, []
        for chunk in held:
            self._out(chunk, now)


def _lines(chunk: Chunk) -> list[Chunk]:
    """``chunk`` cut after each LF."""
    out, data = [], chunk.data
    while data:
        cut = data.find(b"\n") + 1 or len(data)
        out.append(Chunk(chunk.t, chunk.dir, data[:cut], chunk.error))
        data = data[cut:]
    return out
