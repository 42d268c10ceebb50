"""The one rulebook: a sans-IO engine that judges an XA-C1 conversation (docs/protocol.md, all of it).

How it works (h11's shape). A caller cuts each line into frames and junk runs (``Framer``) and feeds
them as events, in the order seen, with their times when it has them: ``host_frame``, ``device_frame``,
``host_junk``, ``device_junk``, then ``tick(now)`` as time passes and ``close(now)`` at the end. Facts
the line cannot show enter as events when a caller knows them: ``power_on()``, ``stop_input(pressed)``,
``move_finished(now)``. Every event returns ``Verdict``s: one for the frame or junk run fed (decoded
frame, violations, what it answers, latency) and a ``no-answer`` verdict for each host line whose answer
window closed. ``knowledge`` holds what is known of the device: each ``Fact`` is ``unknown``, ``known``
(established by the conversation or an out-of-band event: judged) or ``learnt`` (read from an answer
with nothing to compare it with: judged from then on). No clock, no port, no thread: times come in.

Pairing (docs/protocol.md "Framing": strict request/answer; "Violation codes": first in, first out).
A host line that must be answered waits in a queue: a well-formed command, and an *error* (a host frame
with an error-severity violation, or a host junk run ending in LF) which must get an alarm answer
("Behaviour the vendor text states"). An answer pairs with the first waiting line of its header sent
before the answer began; failing that with the head of the queue (an alarm answer fits any line). The
lines it skips got no answer (``no-answer``): one silent exchange never shifts later pairs. A device
junk run inside the head's answer window is the head's garbled answer. A line's answer window closes
at its last byte + ``no_answer_timeout`` (+ twice the estimated move time for 0MP/0MV, silent item 17);
without times, at ``close()``. A host line sent while another waits is ``overlapping-command`` (without
times, order cannot tell it from the first line left unanswered: the verdict says so); the overlapped
line itself is not owed an answer. A line sent during a move is ``command-during-motion`` and is
discarded by the device (silent item 10).

The rules, each written once below (whose fault: ``spec.VIOLATION_TABLE[code].side(sender)``). Each
violation names its row of the rulebook (``rules.RULE_ROWS``: code, basis and so severity; a rule that is
our reading is a notice unless ``readings="error"``); docs/protocol.md "Violation codes" is generated
from those rows. Where each code is found:

| code | on | rule (docs/protocol.md) |
|---|---|---|
| framing codes | the frame | ``codec.diagnose``: the frame table ("Framing", "Fields", "Frames") |
| ``overlapping-command`` | host line | sent while an earlier line is owed its answer ("Framing") |
| ``command-during-motion`` | host line | sent while a move's answer is awaited ("Behaviour") |
| ``alarm-ignored`` | host line | not a well-formed 0%C after an alarm answer ("Behaviour": latch; a notice:
  our reading, the vendor states no duty) |
| ``comm-error-storm`` | host line | the storm run reached the limit (host duty): the run counts ``0%%01``
  answers, the reset answer neither counts nor ends it, any other answer ends it; a garbled answer (junk,
  or a frame whose fields cannot be read) neither counts nor ends it |
| ``storm-recovery`` | host line | a well-formed 0%C, or the first line after its 0%C00, at the storm limit
  (a notice: our reading) |
| ``no-answer`` | its own verdict | a line's window closed, or a later line was answered ("Behaviour") |
| ``error-accepted`` | answer | a normal answer to an error ("Behaviour": errors get ``0%%Ec``) |
| ``answer-mismatch`` | answer | another command's answer, or another N ("Frames") |
| ``echo-mismatch`` | answer | an echo with other field values; case alone is the notice ("Behaviour") |
| ``latch-broken`` | answer | a normal answer while an alarm is latched; a latched code changing to
  another than 0E (after 0E: only where the stop input is known pressed); a reset (0%C) answered with an
  alarm other than 0E: the reset did not work; an alarm a reset cleared during an emergency stop coming
  back, or one held under the stop forgotten, after the release ("Behaviour": latch and reset; silent
  item 3; our choice of code for the failed reset) |
| ``estop-cleared`` | answer | 0%C00 while the stop input is *known* pressed (silent item 3) |
| ``readback-mismatch`` | answer | a point (0WP, 0WC, an earlier 0RP), the OUT ports (0WS, an earlier
  0RS), the position (0MV, 0MP N to a known point, an earlier 0RC), the version read back otherwise; 0RC
  answering a position while the axis is known not homed ("Behaviour": 0RC before homing); 0RC answering
  Pos FFFFFF is the device stating it is not homed: learnt, never judged |
| ``unsolicited-answer`` | answer | nothing waits for it ("Violation codes") |
| ``garbage`` | junk | bytes that form no frame ("Framing") |

Knowledge changes only on a clean exchange (a decoded, rule-abiding answer to a command; what each
command reads and writes of it is one handler a header, declared in the table ``_LEARNERS``): a command
refused with an alarm takes no effect (silent item 18); a garbled, missing or faulty answer makes what
the command would have changed unknown. What docs/protocol.md leaves open is never judged: it becomes
``unknown`` and is learnt from the next answer (the alarm code of an error, item 1; the OUT ports after
0MP N and 0RC's O, item 8; the position after homing, item 7; 0WC's V, A, O, item 4; what the axis does
after the stop input is released, item 3, unless the caller says; the OUT ports, the position and homing
after 0CM0, which hands the controller to the external I/O, item 11).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, Generic, Literal, NamedTuple, TypeVar

from . import motion, rules, spec
from .codec import header_of, read_frame, show_bytes
from .errors import Violation
from .frames import (
    Frame,
    MoveDirect,
    MovePoint,
    PointAnswer,
    ReadCurrent,
    ReadCurrentAnswer,
    ReadOutputs,
    ReadPoint,
    ReadPointAnswer,
    ReadVersion,
    StoreCurrent,
    StoreCurrentAnswer,
    SwitchMode,
    WriteOutputs,
    WritePoint,
)
from .points import PointData

T = TypeVar("T")
Status = Literal["unknown", "known", "learnt"]
UNKNOWN: Final = "unknown"
KNOWN: Final = "known"
LEARNT: Final = "learnt"
HOST: Final = spec.HOST_SIDE
DEVICE: Final = spec.DEVICE_SIDE
_ALARM: Final = spec.ALARM_HEADER  # the alarm answer's header (0%%)
_RESET: Final = spec.RESET_HEADER  # the alarm reset's (0%C)
STROKE_END: Final = spec.UNKNOWN_POSITION - 1  # the farthest position a move can reach (silent item 5)

_BEHAVIOUR: Final = 'docs/protocol.md "Behaviour the vendor text states"'
_SILENT: Final = 'docs/protocol.md "Where the vendor text is silent"'
_CODES: Final = 'docs/protocol.md "Violation codes"'
_FRAMES: Final = 'docs/protocol.md "Frames"'


class Fact(NamedTuple, Generic[T]):
    """One thing known of the device: its value and how it is known (``unknown``, ``known``, ``learnt``)."""

    value: T | None = None
    status: Status = UNKNOWN

    @property
    def judged(self) -> bool:
        """Is an answer compared with it (known or learnt)?"""
        return self.status != UNKNOWN


@dataclass
class Knowledge:
    """What the conversation established about the device. ``latched``: the latched alarm code (value
    None and known: nothing latched); ``storm_run``: ``0%%01`` answers in a row; ``stop_pressed``: the
    emergency stop input, known only from an out-of-band event; ``under_stop``: the alarm latched when
    the emergency stop came, held under it until a reset; ``stop_cleared``: the alarm a reset cleared
    during the stop (it must not come back after the release)."""

    latched: Fact[int] = field(default_factory=Fact)
    storm_run: int = 0
    homed: Fact[bool] = field(default_factory=Fact)
    position: Fact[int] = field(default_factory=Fact)
    points: dict[int, Fact[PointData]] = field(default_factory=dict)
    outputs: Fact[int] = field(default_factory=Fact)
    mode: Fact[int] = field(default_factory=Fact)
    version: Fact[str] = field(default_factory=Fact)
    stop_pressed: Fact[bool] = field(default_factory=Fact)
    under_stop: Fact[int] = field(default_factory=Fact)
    stop_cleared: Fact[int] = field(default_factory=Fact)

    def point(self, n: int) -> Fact[PointData]:
        return self.points.get(n, _NOT_KNOWN)


_NOT_KNOWN: Final[Fact] = Fact()  # an unknown fact (immutable: shared)
_NOTHING_SKIPPED: Final = ()  # ``_pair``: no line skipped (the usual answer)

VerdictKind = Literal["host-frame", "device-frame", "host-junk", "device-junk", "no-answer", "cut"]


class Verdict(NamedTuple):
    """The engine's judgement of one event. ``i``: the event's number among frames and junk runs (None
    for ``no-answer``); ``sender``: whose bytes; ``header``: the spec header read (None when unknown);
    ``frame``: the lenient decode; ``violations``: what is wrong, each with a sentence citing
    docs/protocol.md; ``reply_to``: the host line answered (``no-answer``: the line left unanswered);
    ``latency_s``: from that line's last byte to this answer's first byte; ``t``: time of the first
    byte (``no-answer``: when the window closed, None without time); ``waited_s``: the window applied
    (on a host frame: the answer window it was given, a move's estimated time doubled included)."""

    kind: VerdictKind
    sender: spec.Side
    i: int | None
    raw: bytes = b""
    header: str | None = None
    frame: Frame | None = None
    violations: tuple[Violation, ...] = ()
    reply_to: int | None = None
    latency_s: float | None = None
    t: float | None = None
    t_last: float | None = None
    waited_s: float | None = None

    @property
    def codes(self) -> tuple[spec.ViolationCode, ...]:
        """Violation codes, each once, in the order found."""
        if not self.violations:
            return ()
        return tuple(dict.fromkeys(v.code for v in self.violations))

    @property
    def sides(self) -> tuple[spec.Side, ...]:
        """Whose fault each of ``codes`` is (docs/protocol.md "Violation codes"; aligned with ``codes``)."""
        return tuple(side_of(code, self.sender) for code in self.codes)

    @property
    def errors(self) -> tuple[Violation, ...]:
        """The violations that break a rule (notices left out)."""
        return tuple(v for v in self.violations if v.is_error)

    @property
    def severities(self) -> tuple[spec.Severity, ...]:
        """The severity of each of ``codes`` (aligned with it): ``error`` when any of its violations is
        an error, else ``notice`` (``xac1_proto.rules``: the severity follows the rule's basis)."""
        worst: dict[spec.ViolationCode, spec.Severity] = {}
        for v in self.violations:
            if worst.get(v.code) != spec.ERROR:
                worst[v.code] = v.severity
        return tuple(worst.values())


# a verdict from its fields in order: ``_make`` skips the keyword handling of the generated ``__new__``
# (two verdicts an exchange)
_verdict: Final = Verdict._make


# the answers that echo their command: the same fields as the command's, so a frame's values in wire order
# (a frame is a tuple of them) are compared with the command's
_ECHOED: Final = frozenset(fs.header for fs in spec.FRAME_SPECS if fs.echo and fs.role == spec.ANSWER)
assert all(spec.SPECS[(h, spec.ANSWER)].field_names == spec.SPECS[(h, spec.COMMAND)].field_names
           for h in _ECHOED), "an echo carries its command's fields"
# headers whose command and answer both carry N (an answer for another N is another command's)
_BOTH_N: Final = frozenset(
    fs.header for fs in spec.FRAME_SPECS if fs.role == spec.COMMAND and "n" in fs.field_names
    and "n" in spec.SPECS[(fs.header, spec.ANSWER)].field_names)


def side_of(code: spec.ViolationCode, sender: spec.Side) -> spec.Side:
    """Whose fault ``code`` is when found in bytes that ``sender`` sent."""
    return spec.VIOLATION_TABLE[code].side(sender)




# well-formed commands that raise no alarm of their own (our reading of vendor §6 and §7): an alarm
# answer to one sent without any deviation is a latched alarm, never a new one (one with a notice may be
# refused: a device may take lower case for an error, silent item 2)
_RAISES_NO_ALARM: Final = frozenset({"0RV", "0RS", "0RC", "0WS", "0CM"})

# kinds of host lines in the queue
_COMMAND: Final = "command"  # a well-formed command: owed its answer
_ERROR: Final = "error"  # a frame breaking the frame table, or a junk line: owed an alarm answer
_DISCARD: Final = "discard"  # sent during a move: discarded by the device (silent item 10)


class _Line:
    """A host line waiting for its answer. ``overlapped``: sent while another line waited (the host's
    fault, not owed an answer); ``deadline``: when its answer window closes (None without time);
    ``plain``: read with no deviation at all, not even a notice (a device may refuse a lower-case
    command with an alarm of its own: silent item 2)."""

    __slots__ = ("i", "kind", "header", "frame", "t_last", "deadline", "waited_s", "overlapped", "is_move",
                 "plain", "junk")

    def __init__(self, i: int, kind: str, header: str | None, frame: Frame | None, t_last: float | None,
                 deadline: float | None, waited_s: float, overlapped: bool = False,
                 is_move: bool = False, plain: bool = False) -> None:
        self.i = i
        self.kind = kind
        self.header = header
        self.frame = frame
        self.t_last = t_last
        self.deadline = deadline
        self.waited_s = waited_s
        self.overlapped = overlapped
        self.is_move = is_move
        self.plain = plain
        self.junk = False  # a host junk run ending in LF: no command (owed an alarm answer: our reading)

    @property
    def owed(self) -> bool:
        """Does silence to it break a rule (no-answer)?"""
        return self.kind != _DISCARD and not self.overlapped

    @property
    def is_reset(self) -> bool:
        """Is it a well-formed alarm reset (0%C)?"""
        return self.kind == _COMMAND and self.header == spec.RESET_HEADER

    def name(self) -> str:
        return f"{self.header or 'line'} #{self.i}"


def _show(name: str, value: object) -> str:
    return spec.FIELDS[name].show(value) if isinstance(value, int) else str(value)


def _is_error(violations: list[Violation]) -> bool:
    return any(v.is_error for v in violations)


class Conversation:
    """One conversation between a host and an XA-C1, judged event by event (see the module docstring).

    ``no_answer_timeout``: seconds after a line's last byte before silence is ``no-answer`` (moves get
    more); ``storm_limit``: ``0%%01`` answers in a row after which a host command is ``comm-error-storm``;
    ``speeds``: the speed table that prices a move's answer window; ``readings``: the severity of the
    rules that are our reading of a silent text (``notice``, the default, or ``error``: ``rules``).
    """

    def __init__(self, *, no_answer_timeout: float = spec.NO_ANSWER_TIMEOUT_S,
                 storm_limit: int = spec.STORM_LIMIT,
                 speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS,
                 readings: rules.Readings = rules.DEFAULT_READINGS) -> None:
        if no_answer_timeout <= 0 or storm_limit < 1:
            raise ValueError("no_answer_timeout must be > 0 and storm_limit >= 1")
        if readings not in rules.READINGS:
            raise ValueError(f"readings must be one of {', '.join(rules.READINGS)}, got {readings!r}")
        self.readings = readings
        self._severity = rules.severities(readings)
        self.no_answer_timeout = no_answer_timeout
        self.storm_limit = storm_limit
        self.speeds = speeds
        self.knowledge = Knowledge()
        self._queue: deque[_Line] = deque()
        self._motion: _Line | None = None
        self._unreset_alarm = False  # an alarm answer came and no well-formed 0%C since
        self._reset_in_storm = False  # the last answer was 0%C00 to a reset sent at the storm limit
        self._next_i = 0
        self._last_t: float | None = None
        self._answer_since: float | None = None  # an answer began at this time and is still arriving
        self._cut: _Line | None = None  # the line whose answer the end of the data cut
        self._cut_since: float | None = None  # when that cut answer began

    def _v(self, rule: str, sentence: str, where: str = _BEHAVIOUR) -> Violation:
        """A conversation-level violation of ``rule`` (``rules.RULES``): the sentence, the rule's
        docs/protocol.md section, the code; its severity under this conversation's readings."""
        code = rules.RULES[rule].code
        return Violation(code, None, f"{sentence}; {where} ({code})", rule, self._severity[rule])

    def _graded(self, violations: tuple[Violation, ...]) -> tuple[Violation, ...]:
        """The decoder's violations with their severity under ``readings`` (the decoder grades them by
        the default)."""
        if self.readings == rules.DEFAULT_READINGS or not violations:
            return violations
        sev = self._severity
        return tuple(v if v.severity == sev[v.rule] else Violation(v.code, v.offset, v.message, v.rule,
                                                                      sev[v.rule]) for v in violations)

    # ---- what callers ask ----

    @property
    def waiting(self) -> bool:
        """Does a host line wait for its answer?"""
        return bool(self._queue)

    @property
    def expecting_answer(self) -> bool:
        """Does a well-formed command (not an error, not a line discarded during a move) wait?"""
        return self._motion is not None or any(w.kind == _COMMAND for w in self._queue)

    @property
    def moving(self) -> bool:
        """Is a move's answer awaited?"""
        return self._motion is not None

    @property
    def halted(self) -> bool:
        """The host duty: has the storm limit been reached (any further command is comm-error-storm)?"""
        return self.knowledge.storm_run >= self.storm_limit

    def rearm(self) -> None:
        """The equipment was checked (the client's ``rearm``): the storm run starts over."""
        self.knowledge.storm_run = 0

    def answer_window(self, command: Frame) -> float:
        """Seconds a command's answer may take after its last byte (silent item 17)."""
        return 2.0 * self.move_time(command) + self.no_answer_timeout

    # ---- out-of-band facts ----

    def power_on(self) -> None:
        """The device was just powered on: not homed, mode 0, nothing latched (docs/protocol.md
        "Behaviour the vendor text states": 0RC before homing, power-on mode)."""
        k = self.knowledge
        k.homed, k.position = Fact(False, KNOWN), _NOT_KNOWN
        k.mode, k.latched = Fact(0, KNOWN), Fact(None, KNOWN)
        k.storm_run = 0
        self._unreset_alarm = False

    def stop_input(self, pressed: bool, *, unhomes: bool = False) -> None:
        """The emergency stop input, as a caller that drives it knows (the simulator). Pressed: alarm
        0E latches and a move stops where it is (silent item 19). Released: 0E clears (silent item 3);
        ``unhomes``: the caller knows the axis must then be homed again (when the stop was on)."""
        k = self.knowledge
        was_on = k.stop_pressed.value is True or k.latched.value == spec.ALARM_ESTOP
        k.stop_pressed = Fact(pressed, KNOWN)
        if pressed:
            self._stop_over(k.latched)
            k.latched = Fact(spec.ALARM_ESTOP, KNOWN)
            k.position, k.outputs = _NOT_KNOWN, _NOT_KNOWN  # nothing stated of the OUT ports across a stop
            return
        if k.latched.value == spec.ALARM_ESTOP:  # an alarm held under the stop is latched again
            k.latched = k.under_stop if k.under_stop.value is not None else Fact(None, KNOWN)
            k.under_stop = _NOT_KNOWN
        if unhomes and was_on:  # a release of a stop that was not on changes nothing
            k.homed, k.position = Fact(False, KNOWN), _NOT_KNOWN

    def move_finished(self, now: float) -> None:
        """A caller knows the move under way has ended: its answer is due within the plain timeout."""
        if self._motion is not None:
            self._motion.deadline = now + self.no_answer_timeout

    # ---- events ----

    def host_frame(self, raw: bytes, t_first: float | None = None, t_last: float | None = None,
                   window: float | None = None) -> list[Verdict]:
        """A frame-shaped host line (from a frame start to LF). ``window``: how long the host will wait
        for its answer, when it says so (the client); else the engine's answer window."""
        if t_first is None:
            out = []
        elif self._queue:  # lines wait: their windows may have closed
            out = self.tick(t_first, self._answer_since)
        else:  # the usual command: nothing waits, so time passing closes no window
            out = []
            if self._last_t is None or t_first > self._last_t:
                self._last_t = t_first
        i = self._next_i
        self._next_i = i + 1
        if type(raw) is not bytes:
            raw = bytes(raw)
        frame, violations, header, error = read_frame(raw, spec.COMMAND)
        if violations and self.readings != rules.DEFAULT_READINGS:
            violations = self._graded(violations)
            error = frame is None or any(v.is_error for v in violations)
        found = [*violations]
        if self._unreset_alarm or self._reset_in_storm or self.knowledge.storm_run >= self.storm_limit:
            found += self._host_duties(header, error)
        if error:
            line = self._enqueue(i, _ERROR, header, None, t_last, found, window)
        else:
            line = self._enqueue(i, _COMMAND, header, frame, t_last, found, window, not violations)
        out.append(_verdict(("host-frame", HOST, i, raw, header, frame, tuple(found), None, None, t_first,
                             t_last, line.waited_s)))
        return out

    def host_junk(self, raw: bytes, t_first: float | None = None, t_last: float | None = None,
                  window: float | None = None) -> list[Verdict]:
        """Host bytes that form no frame. A run ending in LF is a line the device must answer as an
        error (docs/protocol.md "Behaviour the vendor text states")."""
        out = self._time(t_first)
        i = self._number()
        found = [Violation("garbage", 0, f"{len(raw)} host bytes that form no frame: {show_bytes(raw)} "
                           f"(garbage)")]
        if raw.endswith(b"\n"):
            self._enqueue(i, _ERROR, None, None, t_last, found, window).junk = True
        out.append(Verdict("host-junk", HOST, i, bytes(raw), violations=tuple(found), t=t_first,
                           t_last=t_last))
        return out

    def device_frame(self, raw: bytes, t_first: float | None = None,
                     t_last: float | None = None) -> list[Verdict]:
        """A frame-shaped device line: an answer. Its arrival passes time to ``t_first``: lines whose
        window closed before it began get ``no-answer`` (``tick``; an answer in time is in time)."""
        queue = self._queue
        out: list[Verdict] = []
        if t_first is not None:
            if self._last_t is None or t_first > self._last_t:
                self._last_t = t_first
            # (``_expire`` decides; while the head's window is open at the answer's start, nothing closes)
            if queue and ((deadline := queue[0].deadline) is None or deadline < t_first):
                self._answer_since = t_first
                out = self._expire(t_first)
        self._answer_since = None
        i = self._next_i
        self._next_i = i + 1
        if type(raw) is not bytes:
            raw = bytes(raw)
        frame, violations, header, _error = read_frame(raw, spec.ANSWER)
        found = [*self._graded(violations)]
        line, skipped = self._pair(header, t_first)
        if skipped:
            out += [self._no_answer(w, t_first, skipped_by=i) for w in skipped if w.owed]
        if line is None:
            found.append(self._v("unsolicited-answer", f"{header or 'this'} answer with no command waiting "
                            f"for it", _CODES))
            reply_to = latency = None
        else:
            reply_to = line.i
            latency = None if line.t_last is None or t_first is None else t_first - line.t_last
        self._judge_answer(line, header, frame, found)
        out.append(_verdict(("device-frame", DEVICE, i, raw, header, frame, tuple(found), reply_to, latency,
                             t_first, t_last, None)))
        return out

    def device_junk(self, raw: bytes, t_first: float | None = None, t_last: float | None = None,
                    line_ended: bool = False) -> list[Verdict]:
        """Device bytes that form no frame. A whole garbled line (ending in LF, or ``line_ended``: a
        partial line the device never finished) inside the head line's answer window is its garbled
        answer; bytes before a frame start are noise, never an answer."""
        out = self._time(t_first, answer=True)
        self._answer_since = None
        i = self._number()
        found = [Violation("garbage", 0, f"{len(raw)} device bytes that form no frame: "
                           f"{show_bytes(raw)} (garbage)")]
        head = self._queue[0] if self._queue else None
        line = None
        whole = raw.endswith(b"\n") or line_ended
        if whole and head is not None and head.kind != _DISCARD and (
                t_first is None or head.deadline is None or t_first <= head.deadline):
            line = self._queue.popleft()
            self._end_motion(line)
            self._outcome_unknown(line)
        latency = None
        if line is not None and line.t_last is not None and t_first is not None:
            latency = t_first - line.t_last
        out.append(Verdict("device-junk", DEVICE, i, bytes(raw), violations=tuple(found),
                           reply_to=None if line is None else line.i, latency_s=latency, t=t_first,
                           t_last=t_last))
        return out

    def tick(self, now: float, answer_since: float | None = None) -> list[Verdict]:
        """Time passes to ``now``: lines whose answer window closed get ``no-answer``. ``answer_since``:
        a device line began at this time and is still arriving (an answer that starts in time is in
        time)."""
        last = self._last_t
        if last is None or now > last:
            self._last_t = now
        self._answer_since = answer_since
        queue = self._queue
        if not queue:
            return []
        deadline = queue[0].deadline
        if len(queue) == 1 and (deadline is None or not deadline < now):
            return []  # the usual tick: the one line waiting is still in its window
        return self._expire(now)

    def ended_inside_frame(self, sender: spec.Side, raw: bytes, t_first: float | None = None,
                           t_last: float | None = None) -> list[Verdict]:
        """The data ended inside a frame of ``sender`` (a capture file or a proxy stopped mid-line): the
        recording ended, not the sender, so no violation. Device bytes that began inside the head line's
        answer window are its answer, cut: that line is cut short at ``close()``, never ``no-answer``."""
        out = self._time(t_first, answer=sender == DEVICE)
        i = self._number()
        head = self._queue[0] if self._queue else None
        reply_to = None
        if sender == DEVICE and head is not None and head.kind != _DISCARD and (
                t_first is None or head.deadline is None or t_first <= head.deadline):
            self._cut, self._cut_since, reply_to = head, t_first, head.i
        out.append(Verdict("cut", sender, i, bytes(raw), reply_to=reply_to, t=t_first, t_last=t_last))
        return out

    def close(self, now: float | None = None) -> list[Verdict]:
        """End of the data: windows closed by ``now`` (default: the last time seen) give ``no-answer``;
        without time, every line still owed an answer does, but one whose answer the end cut
        (``ended_inside_frame``). Returns also the lines cut short (``waiting`` afterwards tells none is
        left)."""
        self._answer_since = self._cut_since if self._cut is not None else None
        end = now if now is not None else self._last_t
        out = self._expire(end) if end is not None else []
        self._answer_since = None
        keep: deque[_Line] = deque()
        for w in self._queue:
            if w.deadline is None and w.owed and w is not self._cut:
                out.append(self._no_answer(w, None))
            elif w.owed:
                keep.append(w)
        self._queue = keep
        return out

    def host_gave_up(self, now: float | None = None) -> list[Verdict]:
        """The host stopped waiting (the client's timeout): every line still owed an answer is
        ``no-answer`` now."""
        out = []
        while self._queue:
            w = self._queue.popleft()
            self._end_motion(w)
            self._outcome_unknown(w)
            if w.owed:
                out.append(self._no_answer(w, now))
        return out

    def cut_short(self) -> int:
        """Lines still owed an answer whose window had not closed when the data ended; forgets them."""
        n = sum(1 for w in self._queue if w.owed)
        self._queue.clear()
        self._motion = None
        return n

    # ---- pairing ----

    def _number(self) -> int:
        i = self._next_i
        self._next_i += 1
        return i

    def _time(self, t: float | None, answer: bool = False) -> list[Verdict]:
        if t is None:
            return []
        return self.tick(t, t if answer else self._answer_since)

    def _enqueue(self, i: int, kind: str, header: str | None, frame: Frame | None, t_last: float | None,
                 found: list[Violation], window: float | None = None, plain: bool = False) -> _Line:
        """Queue a host line, judging when it was sent (docs/protocol.md "Framing": strict request/answer);
        a well-formed move sent while nothing is latched is the move under way."""
        overlapped = False
        if self._motion is not None or self._queue:
            kind, overlapped = self._sent_while_waiting(kind, header, t_last, found)
        is_move = kind == _COMMAND and header in spec.MOVE_HEADERS
        if window is None:
            window = self.answer_window(frame) if is_move and frame is not None else self.no_answer_timeout
        line = _Line(i, kind, header, frame, t_last, None if t_last is None else t_last + window, window,
                     overlapped, is_move, plain)
        self._queue.append(line)
        if is_move and not overlapped and self.knowledge.latched.value is None:
            self._motion = line
        return line

    def _sent_while_waiting(self, kind: str, header: str | None, t_last: float | None,
                            found: list[Violation]) -> tuple[str, bool]:
        """A host line sent while a move's answer or another line's is awaited: its kind (discarded during
        a move) and whether it overlaps a line owed an answer."""
        what = header or "this line"
        if self._motion is not None:
            found.append(self._v("command-during-motion", f"{what} sent while the move {self._motion.name()} "
                            f"waits for its answer"))
            return _DISCARD, False
        first = next((w for w in self._queue if w.owed), None)
        if first is None:
            return kind, False
        detail = f"{what} sent before the answer to {first.name()}"
        if first.t_last is None and t_last is None:
            detail += (f"; the capture has no time, so this looks the same as {first.name()} left "
                       f"unanswered and the host going on after waiting (no-answer)")
        found.append(self._v("overlapping-command", detail, 'docs/protocol.md "Framing"'))
        return kind, True

    def _pair(self, header: str | None, t: float | None) -> tuple[_Line | None, list[_Line] | tuple[()]]:
        """The line an answer belongs to, and the lines it shows were skipped (module docstring): the
        first line of its header sent before the answer began (a line discarded during a move only when
        it alone waits); the usual answer is the head's, nothing skipped."""
        queue = self._queue
        chosen: _Line | None = None
        if queue and header is not None and header != _ALARM:
            alone = len(queue) == 1
            for w in queue:
                if w.header == header and (t is None or w.t_last is None or w.t_last <= t) \
                        and (alone or w.kind != _DISCARD):
                    chosen = w
                    break
            if chosen is queue[0]:
                queue.popleft()
                if self._motion is chosen:
                    self._motion = None
                return chosen, _NOTHING_SKIPPED
        return self._pair_past(chosen, header)

    def _pair_past(self, chosen: _Line | None, header: str | None) -> tuple[_Line | None, list[_Line]]:
        """``_pair`` when the answer is not the head's: ``chosen``, the line of its header, else the first
        line not discarded during a move (an alarm answer fits any line; a discarded line only when it
        alone waits and the answer fits it); the lines before it were skipped."""
        queue = self._queue
        if chosen is None:
            for w in queue:
                fits = header == _ALARM or (w.header is not None and w.header == header)
                if w.kind != _DISCARD or (fits and len(queue) == 1):
                    chosen = w
                    break
        skipped: list[_Line] = []
        while queue:
            w = queue.popleft()
            self._end_motion(w)
            if w is chosen:
                return w, skipped
            skipped.append(w)
            self._outcome_unknown(w)
        return None, skipped

    def _end_motion(self, w: _Line) -> None:
        if self._motion is w:
            self._motion = None

    def _expire(self, now: float) -> list[Verdict]:
        out: list[Verdict] = []
        head = self._queue[0] if self._queue else None
        if head is None or (self._answer_since is not None and head.deadline is not None
                            and self._answer_since <= head.deadline):
            return out
        if len(self._queue) == 1:
            if head.deadline is None or not head.deadline < now:
                return out  # its window is still open (the usual tick)
        elif all(w.deadline is None or not w.deadline < now for w in self._queue):
            return out
        keep: deque[_Line] = deque()
        for w in self._queue:
            if w.deadline is not None and w.deadline < now:
                self._end_motion(w)
                self._outcome_unknown(w)
                if w.owed:
                    out.append(self._no_answer(w, w.deadline))
            else:
                keep.append(w)
        self._queue = keep
        return out

    def _no_answer(self, w: _Line, t: float | None, skipped_by: int | None = None) -> Verdict:
        owed = "an alarm answer (an error must be answered with one)" if w.kind == _ERROR else "its answer"
        if skipped_by is not None:
            when = f"the device answered a later line instead (#{skipped_by})"
        elif t is None:
            when = "the data ended first"
        else:
            when = f"nothing came within {w.waited_s:.3f} s of its last byte"
        rule = "no-answer-junk" if w.junk else "no-answer-error" if w.kind == _ERROR else "no-answer"
        violation = self._v(rule, f"{w.name()} got no answer: it is owed {owed}, but {when}")
        return Verdict("no-answer", HOST, None, header=w.header, violations=(violation,), reply_to=w.i,
                       t=t, waited_s=None if t is None else w.waited_s)

    # ---- host duties ----

    def _host_duties(self, header: str | None, error: bool) -> list[Violation]:
        """Storm and alarm-ignored (docs/protocol.md "Behaviour the vendor text states": host duty,
        latched alarm)."""
        k = self.knowledge
        out = []
        what = header or "this frame"
        good_reset = header == spec.RESET_HEADER and not error
        if k.storm_run >= self.storm_limit and (good_reset or self._reset_in_storm):
            which = "an alarm reset" if good_reset else "the first command after a successful alarm reset"
            out.append(self._v("storm-recovery",
                               f"{what}, {which}, sent after {k.storm_run} communication-error "
                          f"answers (0%%01) in a row: recovering, which the vendor text does not forbid"))
        elif k.storm_run >= self.storm_limit:
            out.append(self._v("comm-error-storm",
                               f"{what} sent after {k.storm_run} communication-error answers "
                          f"(0%%01) in a row; the host must stop after {self.storm_limit}"))
        self._reset_in_storm = False
        if self._unreset_alarm and not good_reset:
            out.append(self._v("alarm-ignored",
                               f"{what} sent after an alarm answer without an alarm reset (0%C)"))
        if good_reset:
            self._unreset_alarm = False
        return out

    # ---- the answer's rules ----

    def _judge_answer(self, line: _Line | None, header: str | None, frame: Frame | None,
                      found: list[Violation]) -> None:
        # the storm run (host duty): ``0%%01`` answers count, the reset answer neither counts nor ends
        # it, any other answer ends it, a faulty one too; an unreadable line (or alarm code) does neither
        k = self.knowledge
        if header == _ALARM:
            if frame is not None:
                code = frame.code  # type: ignore[attr-defined]
                k.storm_run = k.storm_run + 1 if code == spec.ALARM_COMM else 0
                self._alarm(line, code, found)
            elif line is not None:
                self._outcome_unknown(line)
            return
        if header is None:
            if line is not None:
                self._outcome_unknown(line)
            return
        if header != _RESET:
            k.storm_run = 0
        if frame is None or line is None:  # (unsolicited: nothing it says is trusted)
            if line is not None:
                self._outcome_unknown(line)
            return
        if line.kind == _ERROR:
            found.append(self._v("error-accepted",
                                 f"{header} answer to {line.name()}, which breaks the frame "
                            f"table: an error is answered with an alarm answer (0%%Ec)"))
            self._outcome_unknown(line)
            return
        if header == _RESET and line.is_reset:
            self._reset_done(found)
            return
        if k.latched.value is not None:
            self._latch_on_normal_answer(line, found)
        elif k.stop_cleared.value is not None:  # answered normally after the release: the alarm the
            k.stop_cleared = _NOT_KNOWN  # reset cleared did not come back; a later one is new
        command = line.frame
        if command is not None and self._pairing(line, command, header, frame, found) \
                and not (found and _is_error(found)):  # a clean exchange: what it establishes
            learn = _LEARNERS.get(header)  # (judged against the mode before this exchange)
            if learn is not None:
                learn(self, command, frame, found)
            if header != SwitchMode.HEADER:
                k.mode = _MODE_1  # silent item 11: communicating gives mode 1
        else:
            self._outcome_unknown(line)

    def _alarm(self, line: _Line | None, code: int, found: list[Violation]) -> None:
        """An alarm answer: it latches (00 latches nothing, silent item 12); a latched code never changes
        but to emergency stop; a reset clears all but 0E; a refused command takes no effect (item 18)."""
        k = self.knowledge
        latched = k.latched.value
        released = latched == spec.ALARM_ESTOP and not self._stop_known_pressed()  # perhaps, unseen
        if line is not None and line.is_reset and code != spec.ALARM_ESTOP:
            found.append(self._v("reset-refused", f"the alarm reset {line.name()} was answered with alarm "
                            f"{code:02X}: 0%C clears every alarm but emergency stop (0E) and answers 0%C00"))
        elif code == k.stop_cleared.value and code != spec.ALARM_ESTOP and line is not None \
                and line.kind == _COMMAND and line.plain and line.header in _RAISES_NO_ALARM:
            found.append(self._v("stop-alarm-back",
                                 f"alarm {code:02X} answers {line.name()} after the emergency "
                            f"stop, but the alarm reset during the stop cleared it: 0%C clears every alarm "
                            f"but emergency stop (0E)"))
        elif latched is not None and code not in (latched, spec.ALARM_ESTOP) and k.latched.judged \
                and not released:
            found.append(self._v("latch-code-changed",
                                 f"alarm {latched:02X} is latched, but the answer is alarm "
                            f"{code:02X}: a latched alarm is repeated until a reset"))
        if code == spec.ALARM_ESTOP and latched != spec.ALARM_ESTOP:
            self._stop_over(k.latched)
        if line is not None and line.is_reset and code == spec.ALARM_ESTOP:
            k.stop_cleared, k.under_stop = k.under_stop, Fact(None, KNOWN)  # vendor §6
        elif code != spec.ALARM_ESTOP and released:  # the stop was released unseen: held or new alarm
            k.under_stop, k.stop_cleared = _NOT_KNOWN, _NOT_KNOWN
        elif code not in (spec.ALARM_ESTOP, spec.ALARM_NONE):  # a new alarm latched after the stop: what
            k.stop_cleared = _NOT_KNOWN  # the reset cleared during it is history, this one is the latched one
        if code != spec.ALARM_NONE:
            k.latched = Fact(code, LEARNT if k.latched.status == UNKNOWN else k.latched.status)
            if line is None or not line.is_reset:
                self._unreset_alarm = True
        if code == spec.ALARM_ESTOP:
            k.position, k.outputs = _NOT_KNOWN, _NOT_KNOWN  # nothing stated of the OUT ports across a stop
        elif code == spec.ALARM_HOMING:  # homing failed: homed or not is learnt from 0RC ("Alarms")
            k.homed, k.position = _NOT_KNOWN, _NOT_KNOWN
        if line is not None:
            k.mode = Fact(1, KNOWN)  # silent item 11: a refused line is communication too
            self._end_motion(line)
            if line.is_move:
                k.position = _NOT_KNOWN  # it may have stopped anywhere (item 19)
                if k.homed.value is not True:
                    k.homed = _NOT_KNOWN  # it may have homed first ("Alarms": homing after each alarm)

    def _reset_done(self, found: list[Violation]) -> None:
        """0%C answered 0%C00: every alarm but 0E clears. Whether 0E was still on is known only where the
        stop input is known (silent item 3); from the line alone the release happened unseen."""
        k = self.knowledge
        k.mode = Fact(1, KNOWN)  # silent item 11: communicating gives mode 1
        self._reset_in_storm = k.storm_run >= self.storm_limit
        if k.stop_pressed.value is True and k.stop_pressed.status == KNOWN:
            found.append(self._v("estop-cleared",
                                 "the alarm reset answered 0%C00 while the emergency stop input "
                            "is pressed: emergency stop (0E) stays latched until the input is released"))
            return  # the device is wrong; the stop is still on
        if k.latched.value == spec.ALARM_ESTOP:
            k.homed, k.position = _NOT_KNOWN, _NOT_KNOWN  # released unseen: what the axis does is item 3
        k.latched = Fact(None, KNOWN)
        k.under_stop, k.stop_cleared = _NOT_KNOWN, _NOT_KNOWN

    def _latch_on_normal_answer(self, line: _Line, found: list[Violation]) -> None:
        k = self.knowledge
        latched = k.latched.value
        if latched is None or line.is_reset:
            return
        if latched == spec.ALARM_ESTOP and not self._stop_known_pressed():
            under = k.under_stop.value
            if under is not None and k.under_stop.judged:
                found.append(self._v("stop-alarm-back",
                                     f"{line.header} got a normal answer after the emergency "
                                f"stop, but alarm {under:02X} was latched before it and no reset cleared it"))
            k.latched = Fact(None, KNOWN)  # the stop input was released (silent item 3)
            k.homed, k.position = _NOT_KNOWN, _NOT_KNOWN
            k.under_stop, k.stop_cleared = _NOT_KNOWN, _NOT_KNOWN
            return
        found.append(self._v("latch-broken", f"{line.header} got a normal answer while alarm {latched:02X} "
                        f"({spec.alarm_meaning(latched)}) should still be latched"))

    def _stop_known_pressed(self) -> bool:
        k = self.knowledge
        return k.stop_pressed.value is True and k.stop_pressed.status == KNOWN

    def _stop_over(self, latched: Fact[int]) -> None:
        """Emergency stop latches over ``latched``: that alarm is held under it until a reset."""
        k = self.knowledge
        if latched.value != spec.ALARM_ESTOP:
            k.under_stop, k.stop_cleared = latched, Fact(None, KNOWN)

    def _pairing(self, line: _Line, cmd: Frame, header: str, frame: Frame, found: list[Violation]) -> bool:
        """Answer-mismatch and echo-mismatch (docs/protocol.md "Frames"; echoes judged by fields, never
        bytes) of the answer ``frame`` to ``line``'s command ``cmd``. True when the answer fits it."""
        if header != line.header:
            found.append(self._v("answer-mismatch", f"{header} answer to the {line.name()} command", _CODES))
            return False
        if header in _ECHOED:
            if tuple.__ne__(frame, cmd):
                mine, theirs = frame.fields(), cmd.fields()
                diff = ", ".join(f"{spec.FIELDS[k].label} {_show(k, v)} (sent {_show(k, theirs.get(k))})"
                                 for k, v in mine.items() if theirs.get(k) != v)
                found.append(self._v("echo-mismatch",
                                     f"{header} echo differs from the command {line.name()}: "
                                f"{diff}"))
                return False
        elif header in _BOTH_N and frame.n != cmd.n:  # type: ignore[attr-defined]
            found.append(self._v("answer-mismatch",
                                 f"{header} answer for N={frame.n:X} to the command "  # type: ignore[attr-defined]
                            f"{line.name()} for N={cmd.n:X}", _CODES))  # type: ignore[attr-defined]
            return False
        return True

    # ---- knowledge and read-back ----

    def _readback(self, found: list[Violation], what: str, seen: object, fact: Fact[T], how: str,
                  rule: str = "readback-mismatch") -> None:
        found.append(self._v(rule, f"{what} reads back {seen}, but the conversation "
                        f"{'established' if fact.status == KNOWN else 'read earlier'} {how}"))

    def _on_switch_mode(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0CM: the mode sent; after 0CM0 the external I/O owns the controller until the next line."""
        k = self.knowledge
        mode = c.mode  # type: ignore[attr-defined]
        k.mode = Fact(mode, KNOWN)
        if mode == 0:  # silent item 11
            k.outputs, k.position = _NOT_KNOWN, _NOT_KNOWN
            if k.homed.value is not True:
                k.homed = _NOT_KNOWN


    def _on_write_point(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0WP: the point is what was written."""
        k = self.knowledge
        k.points[c.n] = Fact(PointData(c.v, c.a, c.o, c.pos), KNOWN)  # type: ignore[attr-defined]


    def _on_store_current(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0WC: the point stored at the position (V, A, O learnt: silent item 4)."""
        k = self.knowledge
        assert isinstance(a, StoreCurrentAnswer)
        pos = k.position
        if pos.judged and a.pos != pos.value:
            self._readback(found, f"0WC{a.n:X}'s Pos", f"{a.pos:06X}", pos,
                           f"the axis at {pos.value:06X}", "readback-position")
        k.points[a.n] = Fact(PointData(a.v, a.a, a.o, a.pos), LEARNT)

    def _on_move_point(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0MP: homed; at the point (as known as the point); the OUT ports unknown after 0MP N (item 8)."""
        k = self.knowledge
        assert isinstance(c, MovePoint)
        k.homed = _HOMED
        point = k.point(c.n)
        k.position = Fact(point.value.pos, point.status) if c.n and point.value is not None else _NOT_KNOWN
        if c.n:
            k.outputs = _NOT_KNOWN  # silent item 8

    def _on_move_direct(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0MV: homed, at the position sent."""
        k = self.knowledge
        k.homed, k.position = _HOMED, Fact(c.pos, KNOWN)  # type: ignore[attr-defined]

    def _on_read_outputs(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0RS: the OUT ports read back."""
        k = self.knowledge
        o = a.o  # type: ignore[attr-defined]
        if k.outputs.judged and o != k.outputs.value:
            self._readback(found, "0RS's O", o, k.outputs, f"O={k.outputs.value}", "readback-outputs")
        elif k.outputs != (o, LEARNT):
            k.outputs = Fact(o, LEARNT)

    def _on_write_outputs(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0WS: the OUT ports are what was written."""
        k = self.knowledge
        if k.outputs != (c.o, KNOWN):  # type: ignore[attr-defined]
            k.outputs = Fact(c.o, KNOWN)  # type: ignore[attr-defined]

    def _on_read_version(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0RV: the version read back."""
        k = self.knowledge
        version = a.version  # type: ignore[attr-defined]
        if k.version.judged and version != k.version.value:
            self._readback(found, "0RV", version, k.version, f"version {k.version.value}",
                           "readback-version")
        else:
            k.version = Fact(version, LEARNT)

    def _on_read_point(self, c: Frame, a: ReadPointAnswer, found: list[Violation]) -> None:
        """0RP: the point read back (against what was written or read before)."""
        k = self.knowledge
        seen = PointData(a.v, a.a, a.o, a.pos)
        fact = k.point(a.n)
        if fact.value is not None and seen != fact.value:
            self._readback(found, f"point {a.n:X}", seen.show(), fact, fact.value.show())
        elif fact.value is None:
            k.points[a.n] = Fact(seen, LEARNT)

    def _on_read_current(self, c: Frame, a: ReadCurrentAnswer, found: list[Violation]) -> None:
        """0RC: before homing N, V, A 0 and Pos FFFFFF (vendor §7 (3), whatever else is known); a homed
        position while the axis is known not homed only where the mode is known 1 throughout (in mode 0,
        after a power-on or an unseen power cycle, the external I/O may home it: §7 (10), silent item 11);
        after a move, where the move went."""
        k = self.knowledge
        unknown = a.pos == spec.UNKNOWN_POSITION
        if unknown and (a.n, a.v, a.a) != (0, 0, 0):
            self._readback(found, "0RC", f"N={a.n:X} V={a.v} A={a.a} Pos={a.pos:06X}", Fact(False, KNOWN),
                           "Pos FFFFFF, which comes with N, V, A 0", "readback-unhomed")
            return
        if k.homed.value is False and k.homed.status == KNOWN and k.mode == _MODE_1 and not unknown:
            self._readback(found, "0RC", f"N={a.n:X} V={a.v} A={a.a} Pos={a.pos:06X}", k.homed,
                           "the axis not homed (0RC then answers N, V, A 0 and Pos FFFFFF)",
                           "readback-unhomed")
            return
        if unknown:  # the device states it is not homed: learnt, never judged (an unseen power cycle...)
            k.homed, k.position = Fact(False, LEARNT), _NOT_KNOWN
            k.outputs = _NOT_KNOWN  # nothing is stated of the OUT ports across a power cycle
            return
        if k.position.judged and a.pos != k.position.value:
            self._readback(found, "0RC's Pos", f"{a.pos:06X}", k.position,
                           f"the axis at {k.position.value:06X}", "readback-position")
            return
        if k.homed.value is not True:
            k.homed = Fact(True, LEARNT)
        if not k.position.judged:  # else it is what was read (a mismatch returned above)
            k.position = Fact(a.pos, LEARNT)

    def _outcome_unknown(self, line: _Line) -> None:
        """A line whose answer is missing, garbled or faulty: what it would change is unknown now."""
        k = self.knowledge
        c = line.frame
        if line.is_move or isinstance(c, (MovePoint, MoveDirect)):
            k.position = _NOT_KNOWN
            if k.homed.value is not True:
                k.homed = _NOT_KNOWN
        if c is None:
            return
        if c.header in ("0WP", "0WC") and hasattr(c, "n"):
            k.points.pop(c.n, None)
        elif c.header == "0WS" or (isinstance(c, MovePoint) and c.n):
            k.outputs = _NOT_KNOWN
        elif c.header == "0CM":
            k.mode = _NOT_KNOWN
        elif line.is_reset:
            k.latched = _NOT_KNOWN

    # ---- move time (silent items 15, 17) ----

    def move_time(self, command: Frame) -> float:
        """Seconds a move (0MP/0MV) may take at worst, homing included; 0 for other commands. Whatever is
        unknown is taken at its worst: an unknown start homes from the far end of the stroke first, an
        unknown point is as far away as the stroke allows at the slowest speed."""
        s, k = self.speeds, self.knowledge
        start = k.position.value if k.homed.value is not False else None
        t = 0.0
        if start is None:
            t += motion.move_time(STROKE_END, s.homing_pps, s.homing_accel)
            start = 0
        if isinstance(command, MoveDirect):
            return t + motion.move_time(command.pos - start, s.direct_speed(command.vel), command.a)
        if isinstance(command, MovePoint):
            if command.n == 0:
                return t + motion.move_time(start, s.homing_pps, s.homing_accel)
            point = k.point(command.n).value
            if point is None:
                far = max(start, STROKE_END - start)
                return t + motion.move_time(far, s.point_speed(1), 1)
            return t + motion.move_time(point.pos - start, s.point_speed(point.v), point.a)
        return t


_MODE_1: Final = Fact(1, KNOWN)
_HOMED: Final = Fact(True, KNOWN)

# The knowledge each command reads and writes on a clean exchange, one handler a header (``_judge_answer``),
# and the read-backs it is judged against;
# 0%C changes only the mode (and the latch, in ``_reset_done``).
_LEARNERS: Final[dict[str, Callable[..., None]]] = {
    ReadPoint.HEADER: Conversation._on_read_point,
    WritePoint.HEADER: Conversation._on_write_point,
    ReadCurrent.HEADER: Conversation._on_read_current,
    StoreCurrent.HEADER: Conversation._on_store_current,
    MovePoint.HEADER: Conversation._on_move_point,
    MoveDirect.HEADER: Conversation._on_move_direct,
    ReadOutputs.HEADER: Conversation._on_read_outputs,
    WriteOutputs.HEADER: Conversation._on_write_outputs,
    ReadVersion.HEADER: Conversation._on_read_version,
    SwitchMode.HEADER: Conversation._on_switch_mode,
}


def point_of(answer: Frame) -> PointData | None:
    """The point data an answer carries (0RP, 0WP, 0WC, 0MP answers), else None."""
    if isinstance(answer, PointAnswer):
        return PointData(answer.v, answer.a, answer.o, answer.pos)
    return None


__all__ = ["Conversation", "Fact", "Knowledge", "PointData", "Verdict", "header_of", "side_of",
           "KNOWN", "LEARNT", "UNKNOWN"]
