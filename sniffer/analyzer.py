"""The sans-IO conversation analyzer: two byte streams in, one record per frame and junk run out.

How it works. Each direction has its own ``xac1_proto.Framer``; every framer event becomes a record:
``FrameBytes`` -> ``FrameRecord`` decoded with the lenient ``diagnose`` (host bytes as commands, device
bytes as answers; its violations are kept as they are), ``Junk`` -> ``JunkRecord`` (``garbage``). Host
frames join a first-in first-out queue of lines waiting for an answer; each device frame takes the
answer slot of the queue (docs/protocol.md "Violation codes": answers pair first in, first out). Time is
passed in (``Chunk.t``, ``tick(now)``); nothing here reads a clock. A conversation-level violation goes
on the record being processed when it is detected; ``no-answer`` gets a ``TimeoutRecord`` of its own.

What waits for an answer (the queue), and what happens when nothing comes:
- a well-formed host frame (no error-severity violation; notices such as ``lowercase-hex`` are fine)
  sent while nothing else waits: a *command*. It must be answered: ``no-answer`` when its deadline
  passes. Deadline: last byte + ``no_answer_timeout``; for 0MP/0MV, last byte + twice the estimated
  move time (``axis.AxisEstimate``, worst case for whatever is unknown) + ``no_answer_timeout``
  (silent item 17). Without timestamps the verdict comes at ``close()``.
- a host frame with an error violation (malformed), and a host junk run ending in LF (a *line*, which a
  device reads as a malformed command): how a device reacts is a silent point (item 1), so they may
  be answered but need not be; a malformed frame takes an alarm answer or an answer of its own header,
  a line only an alarm answer.
- a command sent while another waits (``overlapping-command``): answered in turn if the device answers
  it, no ``no-answer`` if it does not.
- a command sent during a move (``command-during-motion``): a device discards it (silent item 10); it
  takes an answer only when nothing else waits and the answer fits it.
A device frame pairs with the head of the queue: a command or an overlapping command always takes it;
an optional entry that the answer does not fit is dropped (answers come in order, so a device that
answers a later line has skipped this one). A device frame with nothing to pair with is
``unsolicited-answer``. Device junk is never an answer. While a device frame that began before the
head's deadline is still arriving, the deadline waits for it (an answer that starts in time is in time).

Rules and their triggers (each on the record named):
- ``echo-mismatch`` (answer): the answer has its command's header, its frame kind is an echo (0WP, 0MV,
  0WS, 0CM) and its decoded fields differ from the command's (fields, not bytes: case is a notice).
- ``answer-mismatch`` (answer): a normal (non-alarm) answer whose header differs from its command's
  (the reset answer to anything but 0%C included), or of a command carrying N (0RP, 0WC, 0MP) with
  another N. Alarm answers fit every command. Not checked when either header is unknown.
- ``unsolicited-answer`` (answer): a device frame with no waiting entry it may pair with.
- ``no-answer`` (timeout record): a command's deadline passed (or, without time, the data ended).
- ``overlapping-command`` (command): a host frame while a command or overlapping command waits, no move
  in progress.
- ``command-during-motion`` (command): a host frame while a move waits for its answer. A move is a
  well-formed 0MP/0MV command that waited for nothing and was sent while no alarm was known latched; it
  lasts until its answer or ``no-answer``. (Instead of ``overlapping-command``, not as well.)
- ``alarm-ignored`` (command): a host frame other than a well-formed 0%C after an alarm answer (code
  other than 00) to anything but a 0%C, with no well-formed 0%C in between. An alarm answer to 0%C
  (emergency stop survives resets) does not call for another reset.
- ``comm-error-storm`` (command): a host frame while ``storm_limit`` or more ``0%%01`` answers came
  since the last normal answer (latched repeats count; the reset answer and other alarms neither count
  nor end the run).
- ``latch-broken`` (answer): a normal answer, paired with a non-reset command, while an alarm other than
  emergency stop is latched (latched by an alarm answer, cleared by a reset answer). Under emergency
  stop a normal answer means the stop input was released (silent item 3): it clears the latch.
- ``estop-cleared`` (answer): a reset answer to 0%C while emergency stop (0E) is latched. (The release
  of the stop input between the alarm and the reset is invisible on the line.)
Unsolicited answers update the state (latch, storm run, position) but are checked for nothing else.

Captures without time (``Chunk.t`` None: raw files, interceptty without ``-T``, sigrok without a
sample rate): order is all there is, and order cannot tell a device that never answered a command from
a host that did not wait for the answer, since both show as two commands with no answer between. The
verdict is ``overlapping-command`` on the second command (that is what the order shows; the first keeps
its place in the queue, so a later answer pairs with it), with a detail saying it may as well be a
``no-answer`` to the first; a command still waiting when the data ends is ``no-answer`` (``close()``).

Capture-tool line errors (``Chunk.error``) go on every record holding a flagged byte, under
``line_errors``; they are not violations.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Final

from xac1_proto import Frame, FrameBytes, Framer, Junk, diagnose, motion, spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.frames import AlarmAnswer

from .axis import AxisEstimate
from .records import FrameRecord, JunkRecord, Record, Tally, TimeoutRecord

NO_ANSWER_TIMEOUT_S: Final = spec.NO_ANSWER_TIMEOUT_S  # docs/protocol.md silent item 17
DEVICE_IDLE_FLUSH_S: Final = 1.0  # a partial device frame this long quiet becomes junk

# kinds of queue entries
COMMAND: Final = "command"
OVERLAP: Final = "overlap"
MALFORMED: Final = "malformed"
LINE: Final = "line"
DISCARD: Final = "discard"
_FIRM: Final = frozenset({COMMAND, OVERLAP})  # take the next answer, whatever it is

_N_CHECKED: Final = frozenset(h for (h, r), fs in spec.SPECS.items()
                              if r == spec.COMMAND and "n" in fs.layout and not fs.echo
                              and "n" in spec.SPECS[(h, spec.ANSWER)].layout)


@dataclass
class _Waiting:
    """A host line waiting for its answer."""

    i: int
    kind: str
    header: str | None
    frame: Frame | None
    t_last: float | None
    deadline: float | None
    waited_s: float
    is_move: bool = False


def header_of(raw: bytes, role: spec.Role) -> str | None:
    """The spec header a frame was read as (a leading letter O read as the digit), else None."""
    head = raw[: spec.HEADER_WIDTH].decode("ascii", "replace")
    if (head, role) in spec.SPECS:
        return head
    if raw[:1] == spec.LETTER_O and ("0" + head[1:], role) in spec.SPECS:
        return "0" + head[1:]
    return None


class _Dedup:
    """Violation codes (each once) with their explanations."""

    def __init__(self) -> None:
        self.codes: list[spec.ViolationCode] = []
        self.details: list[str] = []

    def add(self, code: spec.ViolationCode, detail: str) -> None:
        if code not in self.codes:
            self.codes.append(code)
        self.details.append(detail)


class Analyzer:
    """Feed ``Chunk``s of both directions in the order seen; get records. See the module docstring."""

    def __init__(self, no_answer_timeout: float = NO_ANSWER_TIMEOUT_S, storm_limit: int = spec.STORM_LIMIT,
                 speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS,
                 device_idle_flush: float | None = DEVICE_IDLE_FLUSH_S) -> None:
        self.no_answer_timeout = no_answer_timeout
        self.storm_limit = storm_limit
        self.device_idle_flush = device_idle_flush
        self.axis = AxisEstimate(speeds)
        self.tally = Tally()
        self._framers: dict[str, Framer] = {HOST: Framer(), DEVICE: Framer()}
        self._errors: dict[str, list[tuple[int, int, str]]] = {HOST: [], DEVICE: []}
        self._queue: deque[_Waiting] = deque()
        self._next_i = 0
        self._last_t: float | None = None
        self._device_since: float | None = None  # time of the oldest pending device byte
        self._device_last: float | None = None  # time of the latest device chunk
        self._motion: _Waiting | None = None
        self._latched: int | None = None
        self._unreset_alarm = False
        self._comm_run = 0
        self._closed = False

    # ---- input ----

    def feed(self, chunk: Chunk) -> list[Record]:
        """Bytes seen on one line; the records they complete (time passing to ``chunk.t`` first)."""
        if self._closed:
            raise RuntimeError("the analyzer is closed")
        if chunk.dir not in (HOST, DEVICE):
            raise ValueError(f"chunk direction must be 'host' or 'device', got {chunk.dir!r}")
        out: list[Record] = []
        if chunk.t is not None:
            out += self.tick(chunk.t)
        framer = self._framers[chunk.dir]
        if chunk.error and chunk.data:
            self._errors[chunk.dir].append((framer.bytes_in, framer.bytes_in + len(chunk.data), chunk.error))
        pending_before = framer.pending
        events = framer.feed(chunk.data, chunk.t)
        if chunk.dir == DEVICE and chunk.data:
            self._device_last = chunk.t
            if framer.pending == 0:
                self._device_since = None
            elif pending_before == 0:
                self._device_since = chunk.t  # else keep the older time: never expire too early
        for event in events:
            out += self._event(chunk.dir, event)
        return out

    def tick(self, now: float) -> list[Record]:
        """Time passes to ``now`` (unix seconds): missed answers and stalled device frames come out."""
        out: list[Record] = []
        self._last_t = now if self._last_t is None else max(self._last_t, now)
        framer = self._framers[DEVICE]
        if (self.device_idle_flush is not None and framer.pending and self._device_last is not None
                and now - self._device_last >= self.device_idle_flush):
            self._device_since = None
            for event in framer.flush():
                out += self._event(DEVICE, event)
        out += self._expire(now)
        return out

    def close(self, now: float | None = None) -> list[Record]:
        """End of data: partial frames come out as junk; a command still waiting is ``no-answer`` when
        its deadline passed by ``now`` (default: the last time seen) or when the data had no time."""
        out: list[Record] = []
        if self._closed:
            return out
        if now is not None:
            out += self.tick(now)
        for direction in (HOST, DEVICE):
            for event in self._framers[direction].flush():
                out += self._event(direction, event)
        self._device_since = None
        end = now if now is not None else self._last_t
        if end is not None:
            out += self._expire(end)
        for w in self._queue:
            if w.kind != COMMAND:
                continue
            if w.deadline is None:
                out.append(self._timeout(w, None))
            else:
                self.tally.unanswered += 1
        self._queue.clear()
        self._closed = True
        return out

    @property
    def waiting(self) -> bool:
        """Does anything the host sent (a command, a malformed frame, a junk line) wait for an answer?"""
        return bool(self._queue)

    @property
    def expecting_answer(self) -> bool:
        """Does a command (not a malformed frame or junk line) wait for its answer?"""
        return self._motion is not None or any(w.kind in _FIRM for w in self._queue)

    def bytes_in(self, direction: str) -> int:
        """Bytes fed so far on one line."""
        return self._framers[direction].bytes_in

    def summary(self) -> dict[str, object]:
        """The summary record (schema's last line) for everything so far."""
        return self.tally.summary()

    # ---- events ----

    def _event(self, direction: str, event: FrameBytes | Junk) -> list[Record]:
        i = self._next_i
        self._next_i += 1
        errors = self._line_errors(direction, event.offset, len(event.raw))
        out: list[Record]
        if isinstance(event, Junk):
            record: Record = JunkRecord(i=i, t=event.t_first, dir=HOST if direction == HOST else DEVICE,
                                        raw=event.raw, reason=event.reason,
                                        details=(f"{len(event.raw)} bytes that form no frame "
                                                 f"({event.reason}) (garbage)",),
                                        line_errors=errors)
            if direction == HOST and event.raw.endswith(b"\n"):
                self._queue.append(self._waiting(i, LINE, None, None, event.t_last))
            out = [record]
        elif direction == HOST:
            out = [self._command(i, event, errors)]
        else:
            out = self._answer(i, event, errors)
        for r in out:
            self.tally.add(r)
        return out

    def _line_errors(self, direction: str, offset: int, length: int) -> tuple[str, ...]:
        ranges = self._errors[direction]
        while ranges and ranges[0][1] <= offset:
            ranges.pop(0)
        return tuple(e for start, end, e in ranges if start < offset + length and end > offset)

    def _waiting(self, i: int, kind: str, header: str | None, frame: Frame | None,
                 t_last: float | None, move_s: float = 0.0) -> _Waiting:
        waited = 2.0 * move_s + self.no_answer_timeout
        deadline = None if t_last is None else t_last + waited
        return _Waiting(i, kind, header, frame, t_last, deadline, waited)

    def _command(self, i: int, event: FrameBytes, errors: tuple[str, ...]) -> FrameRecord:
        frame, violations = diagnose(event.raw, spec.COMMAND)
        found = _Dedup()
        for v in violations:
            found.add(v.code, v.message)
        header = frame.header if frame is not None else header_of(event.raw, spec.COMMAND)
        malformed = frame is None or any(spec.VIOLATIONS[v.code][0] == spec.ERROR for v in violations)
        good_reset = header == spec.RESET_HEADER and not malformed
        what = header or "this frame"
        if self._comm_run >= self.storm_limit:
            found.add("comm-error-storm", f"{what} sent after {self._comm_run} communication-error answers "
                      f"in a row; the host must stop after {self.storm_limit} (comm-error-storm)")
        if self._unreset_alarm and not good_reset:
            found.add("alarm-ignored", f"{what} sent after an alarm answer without an alarm reset (0%C) "
                      f"(alarm-ignored)")
        if good_reset:
            self._unreset_alarm = False
        if self._motion is not None:
            kind = DISCARD
            found.add("command-during-motion", f"{what} sent while the move #{self._motion.i} "
                      f"({self._motion.header}) waits for its answer (command-during-motion)")
        else:
            firm = next((w for w in self._queue if w.kind in _FIRM), None)
            if firm is not None:
                detail = f"{what} sent before the answer to #{firm.i} ({firm.header or 'unknown'})"
                if firm.t_last is None and event.t_last is None:
                    detail += (f"; the capture has no time, so this looks the same as #{firm.i} left "
                               f"unanswered and the host going on after waiting (no-answer)")
                found.add("overlapping-command", f"{detail} (overlapping-command)")
            kind = MALFORMED if malformed else (OVERLAP if firm is not None else COMMAND)
        is_move = header in spec.MOVE_HEADERS and frame is not None and not malformed
        move_s = self.axis.move_time(frame) if is_move and frame is not None else 0.0
        w = self._waiting(i, kind, header, frame, event.t_last, move_s)
        if is_move and kind == COMMAND and self._latched is None:
            w.is_move = True
            self._motion = w
        self._queue.append(w)
        return FrameRecord(i=i, t=event.t_first, dir=HOST, raw=event.raw, header=header, frame=frame,
                           violations=tuple(found.codes), details=tuple(found.details),
                           t_last=event.t_last, line_errors=errors)

    def _fits(self, w: _Waiting, header: str | None, is_alarm: bool) -> bool:
        if is_alarm:
            return True
        return w.kind != LINE and header is not None and header == w.header

    def _pair(self, header: str | None, is_alarm: bool) -> _Waiting | None:
        """Take the queue entry this answer belongs to (see the module docstring), or None."""
        while self._queue:
            w = self._queue[0]
            if w.kind in _FIRM or (self._fits(w, header, is_alarm)
                                   and (w.kind != DISCARD or len(self._queue) == 1)):
                self._queue.popleft()
                return w
            self._queue.popleft()  # skipped by the device: answers come in order
            self._end_motion(w)
        return None

    def _end_motion(self, w: _Waiting) -> None:
        if self._motion is w:
            self._motion = None

    def _answer(self, i: int, event: FrameBytes, errors: tuple[str, ...]) -> list[Record]:
        frame, violations = diagnose(event.raw, spec.ANSWER)
        found = _Dedup()
        for v in violations:
            found.add(v.code, v.message)
        header = frame.header if frame is not None else header_of(event.raw, spec.ANSWER)
        alarm = frame.code if isinstance(frame, AlarmAnswer) else None
        is_alarm = header == spec.ALARM_HEADER
        w = self._pair(header, is_alarm)
        latency = None
        if w is None:
            found.add("unsolicited-answer", f"{header or 'this frame'} answer with no command waiting "
                      f"for it (unsolicited-answer)")
        else:
            self._end_motion(w)
            if w.t_last is not None and event.t_first is not None:
                latency = event.t_first - w.t_last
            if not is_alarm:
                self._check_pairing(w, header, frame, found)
        self._update_state(w, header, frame, alarm, found)
        record = FrameRecord(i=i, t=event.t_first, dir=DEVICE, raw=event.raw, header=header, frame=frame,
                             violations=tuple(found.codes), details=tuple(found.details),
                             reply_to=None if w is None else w.i, latency_s=latency,
                             t_last=event.t_last, line_errors=errors)
        return [record]

    def _check_pairing(self, w: _Waiting, header: str | None, frame: Frame | None, found: _Dedup) -> None:
        if w.header is None or header is None:
            return
        if header != w.header:
            found.add("answer-mismatch", f"{header} answer to the {w.header} command #{w.i} "
                      f"(answer-mismatch)")
            return
        cmd = w.frame
        if cmd is None or frame is None:
            return
        if frame.frame_spec().echo:
            if frame.fields() != cmd.fields():
                diff = ", ".join(f"{spec.FIELDS[k].label} {v} vs {cmd.fields().get(k)}"
                                 for k, v in frame.fields().items() if cmd.fields().get(k) != v)
                found.add("echo-mismatch", f"{header} echo differs from the command #{w.i}: {diff} "
                          f"(echo-mismatch)")
        elif header in _N_CHECKED and frame.fields().get("n") != cmd.fields().get("n"):
            found.add("answer-mismatch", f"{header} answer for N={frame.fields().get('n'):X} to the "
                      f"command #{w.i} for N={cmd.fields().get('n'):X} (answer-mismatch)")

    def _update_state(self, w: _Waiting | None, header: str | None, frame: Frame | None,
                      alarm: int | None, found: _Dedup) -> None:
        if frame is None:
            return  # an answer that could not be read changes nothing we track
        to_reset = w is not None and w.header == spec.RESET_HEADER and w.kind != MALFORMED
        if alarm is not None:
            if alarm == spec.ALARM_COMM:
                self._comm_run += 1
            if alarm != spec.ALARM_NONE:
                self._latched = alarm
                if not to_reset:
                    self._unreset_alarm = True
                if (w is not None and w.header in spec.MOVE_HEADERS) or alarm == spec.ALARM_ESTOP:
                    self.axis.forget_position()
            return
        if header == spec.RESET_HEADER:
            if to_reset or w is None:
                if self._latched == spec.ALARM_ESTOP and w is not None:
                    found.add("estop-cleared", "the alarm reset answered 0%C00 while emergency stop (0E) "
                              "was latched: it must stay latched until the stop input is released "
                              "(estop-cleared)")
                self._latched = None
            return
        self._comm_run = 0
        if w is not None and not to_reset and self._latched is not None:
            if self._latched == spec.ALARM_ESTOP:
                self._latched = None  # the stop input was released (silent item 3)
            else:
                found.add("latch-broken", f"a normal answer while alarm {self._latched:02X} "
                          f"({spec.alarm_meaning(self._latched)}) should still be latched (latch-broken)")
        self.axis.learn(frame)

    def _expire(self, now: float) -> list[Record]:
        out: list[Record] = []
        if not self._queue:
            return out
        head = self._queue[0]
        if (self._device_since is not None and head.deadline is not None
                and self._device_since <= head.deadline):
            return out  # an answer began in time and is still arriving
        keep: deque[_Waiting] = deque()
        for w in self._queue:
            if w.deadline is not None and w.deadline < now:
                self._end_motion(w)
                if w.kind == COMMAND:
                    out.append(self._timeout(w, w.deadline))
            else:
                keep.append(w)
        self._queue = keep
        return out

    def _timeout(self, w: _Waiting, t: float | None) -> TimeoutRecord:
        if t is None:
            detail = f"{w.header or 'command'} #{w.i} got no answer before the end of the data (no-answer)"
        else:
            detail = (f"{w.header or 'command'} #{w.i} got no answer within {w.waited_s:.3f} s of its "
                      f"last byte (no-answer)")
        record = TimeoutRecord(command=w.i, t=t, header=w.header, waited_s=None if t is None else w.waited_s,
                               details=(detail,))
        self.tally.add(record)
        return record


def analyze(chunks: list[Chunk] | tuple[Chunk, ...], **options: object) -> list[Record]:
    """Every record of a whole capture (a convenience for tests and small files)."""
    analyzer = Analyzer(**options)  # type: ignore[arg-type]
    out: list[Record] = []
    for chunk in chunks:
        out += analyzer.feed(chunk)
    out += analyzer.close()
    return out

