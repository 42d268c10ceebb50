"""The host lines waiting for their answers, and the one place that decides whether a window has closed
(docs/protocol.md "Framing": strict request/answer; silent item 17: the answer window).

How this works: the engine (``conversation``) queues each host line it owes an answer to as a
``WaitingLine`` with its ``deadline`` (its last byte + its answer window; None without time). ``Waiting``
holds them in order with a time before which no window can close at hand (``due``: at most the earliest
deadline; a line's leaving does not raise it, ``closed`` makes it exact), so asking whether time passing
closes a window is one comparison while nothing can close (every frame asks).
``closed(now, since)`` is the only judgement of a closed window: a line whose deadline is before ``now``
is closed, unless an answer began at ``since`` within the head's window (an answer that starts in time
is in time); ``open_at(line, t)`` is its inverse for one line. No clock: times come in.
"""

from __future__ import annotations

from collections import deque
from typing import Final

from . import spec
from .frames import Frame

COMMAND: Final = "command"  # a well-formed command: owed its answer
ERROR: Final = "error"  # a frame breaking the frame table, or a junk line: owed an alarm answer
DISCARD: Final = "discard"  # sent during a move: discarded by the device (silent item 10)
_NEVER: Final = float("inf")
_deque_append: Final = deque.append  # (a global, not a look-up on the class at each line)

# well-formed commands that raise no alarm of their own (our reading of vendor §6 and §7): an alarm
# answer to one sent without any deviation is a latched alarm, never a new one (one with a notice may be
# refused: a device may take lower case for an error, silent item 2)
RAISES_NO_ALARM: Final = frozenset({"0RV", "0RS", "0RC", "0WS", "0CM"})


class WaitingLine:
    """A host line waiting for its answer. ``kind``: ``COMMAND``, ``ERROR`` or ``DISCARD``;
    ``overlapped``: sent while another line waited (the host's fault, not owed an answer); ``deadline``:
    when its answer window closes (None without time); ``harmless``: a command of ``RAISES_NO_ALARM``
    read with no deviation at all, not even a notice (a device may refuse a lower-case command with an
    alarm of its own: silent item 2), and not discarded;
    ``junk``: a host junk run ending in LF, no command (owed an alarm answer: our reading); ``guessed``: a
    move whose window rests only on the guessed speed table (silent items 15, 17)."""

    __slots__ = ("i", "kind", "header", "frame", "t_last", "deadline", "waited_s", "overlapped", "is_move",
                 "plain", "junk", "on_guess", "is_reset")

    def __init__(self, i: int, kind: str, header: str | None, frame: Frame | None, t_last: float | None,
                 waited_s: float, overlapped: bool = False, is_move: bool = False, plain: bool = False,
                 junk: bool = False, guessed: bool = False) -> None:
        self.i = i
        self.kind = kind
        self.header = header
        self.frame = frame
        self.t_last = t_last
        self.deadline = None if t_last is None else t_last + waited_s
        self.waited_s = waited_s
        self.overlapped = overlapped
        self.is_move = is_move
        self.plain = plain  # read with no deviation at all
        self.junk = junk
        self.on_guess = guessed  # its window, were it a move's, rests on the guessed speed table
        self.is_reset = kind == COMMAND and header == spec.RESET_HEADER  # a well-formed alarm reset (0%C)?

    # (asked only when something went wrong: worked out then, not for every line)

    @property
    def harmless(self) -> bool:
        """A command of ``RAISES_NO_ALARM`` read with no deviation, not discarded (class docstring)?"""
        return self.plain and self.kind == COMMAND and self.header in RAISES_NO_ALARM

    @property
    def guessed(self) -> bool:
        """A move whose window rests only on the guessed speed table?"""
        return self.is_move and self.on_guess

    @property
    def owed(self) -> bool:
        """Does silence to it break a rule (no-answer)?"""
        return self.kind != DISCARD and not self.overlapped

    def name(self) -> str:
        return f"{self.header or 'line'} #{self.i}"


class Waiting(deque[WaitingLine]):
    """The lines waiting for their answers, first sent first (a deque), with ``due`` at hand: no window
    closes before it (at most the earliest deadline). Lines enter by ``append``, which lowers ``due``, and
    leave by ``popleft`` (the deque's own: ``due`` stays where it was, still a time no window closes
    before), ``clear`` or ``keep``."""

    __slots__ = ("due",)

    def __init__(self) -> None:
        super().__init__()
        self.due = _NEVER  # no window closes before it (inf: none can)

    @property
    def head(self) -> WaitingLine | None:
        """The first line waiting, if any."""
        return self[0] if self else None

    def append(self, line: WaitingLine) -> None:
        _deque_append(self, line)
        if line.deadline is not None and line.deadline < self.due:
            self.due = line.deadline

    def take_own_answer(self, header: str, t: float | None) -> WaitingLine | None:
        """The head line, taken out, when an answer of ``header`` (a command's, not an alarm) begun at
        ``t`` is its own: of its header, sent before ``t``, not discarded during a move unless it alone
        waits. None when the answer is not the head's (the engine then looks further down the queue)."""
        if not self:
            return None
        head = self[0]
        if head.header != header \
                or (t is not None and head.t_last is not None and head.t_last > t) \
                or (head.kind == DISCARD and len(self) > 1):
            return None
        self.popleft()
        if not self:  # the usual answer: no line waits now, no window can close
            self.due = _NEVER
        return head

    def clear(self) -> None:
        super().clear()
        self.due = _NEVER

    def keep(self, lines: deque[WaitingLine]) -> None:
        """Only ``lines`` (in order) wait now."""
        super().clear()
        self.extend(lines)
        self._recount()

    def reschedule(self, line: WaitingLine, deadline: float) -> None:
        """``line``'s window now closes at ``deadline`` (a caller knows more: the move ended)."""
        line.deadline = deadline
        self._recount()

    def _recount(self) -> None:
        self.due = min((w.deadline for w in self if w.deadline is not None), default=_NEVER)

    # ---- the windows ----

    def open_at(self, line: WaitingLine, t: float | None) -> bool:
        """Is ``line``'s window open at ``t`` (always, without time)?"""
        return t is None or line.deadline is None or t <= line.deadline

    def closed(self, now: float, since: float | None) -> list[WaitingLine]:
        """The lines whose window closed before ``now``, taken out of the queue in order. ``since``: an
        answer began then and is still arriving; begun within the head's window, it closes nothing."""
        if not self.due < now:
            return []
        if not self:  # the lines that set ``due`` have left
            self.due = _NEVER
            return []
        head = self[0]
        if since is not None and head.deadline is not None and since <= head.deadline:
            return []
        closed: list[WaitingLine] = []
        kept: deque[WaitingLine] = deque()
        for w in self:
            (closed if w.deadline is not None and w.deadline < now else kept).append(w)
        self.keep(kept)
        return closed
