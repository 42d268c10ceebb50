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

One direction (``directions="host"`` or ``"device"``: a capture that holds one line's bytes only). Only
what one direction's bytes show is judged: each frame and junk run by its own bytes, the sender's duties
(docs/protocol.md "Violation codes", ``spec.VIOLATION_TABLE[code].duty == spec.SENDER``). Nothing pairs,
latches or waits, since the other direction cannot be in the data: a host line owed an answer is counted
(``unanswerable``), never queued, so memory stays flat whatever the capture's length.

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

The rules are data. Each violation names its row of the rulebook (``rules.RULE_ROWS``: code, whose
duty, basis and so severity; a rule that is our reading is a notice unless ``readings="error"``), from
which docs/protocol.md "Violation codes" is generated. The alarm latch, the emergency stop, the reset and
the storm run are the declared state machines of ``latch`` (``LATCH``, ``HOST_DUTY``: which rule each
event breaks in each state, and what it does); whether a window has closed is decided in one place,
``waiting.Waiting.closed``; what each command teaches and forgets is one row a header (``HEADER_RULES``).
A violation is recorded as its rule and the few values its sentence needs; the sentence
(``sentences``) is made only when shown. The framing codes come from the decoder (``codec``).

Knowledge changes only on a clean exchange (a decoded, rule-abiding answer to a command; what each
command reads and writes of it is the ``learn`` column of its row of ``HEADER_RULES``): a command
refused with an alarm takes no effect (silent item 18); a garbled, missing or faulty answer makes what
the command would have changed unknown (the row's ``forget`` column). What docs/protocol.md leaves
open is never judged: it becomes ``unknown`` and is learnt from the next answer (the alarm code of an
error, item 1; the OUT ports after 0MP N and 0RC's O, item 8; the position after homing, item 7, is the
Pos the homing answer states; 0WC's V, A, O, item 4; what the axis does after the stop input is
released, item 3, unless the caller says; the OUT ports, the position and homing after 0CM0, which
hands the controller to the external I/O, item 11).
"""

from __future__ import annotations

import functools
import operator
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, Generic, Literal, NamedTuple, TypeVar

from . import motion, rules, sentences, spec
from .codec import Reading, header_of, read_frame
from .errors import Violation
from .frames import (
    AlarmReset,
    Frame,
    MoveDirect,
    MovePoint,
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
from .latch import ALARM_EVENTS, HOST_DUTY, LATCH, Effect, LatchEvent, LatchState, StormState
from .points import PointData
from .waiting import COMMAND, DISCARD, ERROR, Waiting, WaitingLine

T = TypeVar("T")
Status = Literal["unknown", "known", "learnt"]
UNKNOWN: Final = "unknown"
KNOWN: Final = "known"
LEARNT: Final = "learnt"
HOST: Final = spec.HOST_SIDE
DEVICE: Final = spec.DEVICE_SIDE
_ALARM: Final = spec.ALARM_HEADER  # the alarm answer's header (0%%)
_RESET: Final = spec.RESET_HEADER  # the alarm reset's (0%C)
Directions = Literal["both", "host", "device"]
BOTH: Final = "both"  # the usual capture: both lines' bytes
DIRECTIONS: Final[tuple[Directions, ...]] = (BOTH, HOST, DEVICE)
STROKE_END: Final = spec.UNKNOWN_POSITION - 1  # the farthest position a move can reach (silent item 5)



class Fact(NamedTuple, Generic[T]):
    """One thing known of the device: its value and how it is known (``unknown``, ``known``, ``learnt``)."""

    value: T | None = None
    status: Status = UNKNOWN

    @property
    def judged(self) -> bool:
        """Is an answer compared with it (known or learnt)? (The engine's learners ask its test, ``status !=
        UNKNOWN``, directly: a property is a call of its own on every answer.)"""
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
# the latch's states and the events of most answers, as constants: on Python 3.11 a member read off its
# Enum class goes through the enum metaclass's ``__getattr__``, ten times the cost of a constant
_FREE, _HELD, _STOP = LatchState.FREE, LatchState.HELD, LatchState.STOP
_STOP_UNSEEN, _STOP_UNSEEN_OVER = LatchState.STOP_UNSEEN, LatchState.STOP_UNSEEN_OVER
_NORMAL, _SAME, _OTHER = LatchEvent.NORMAL, LatchEvent.SAME, LatchEvent.OTHER
_SWITCH_MODE: Final = SwitchMode.HEADER  # (a class's attribute is a look-up a read on Python 3.11)
_NOTHING_SKIPPED: Final = ()  # ``_pair``: no line skipped (the usual answer)

# a verdict's codes (each once), whose fault each is, and each one's worst severity
_Tally = tuple[tuple[spec.ViolationCode, ...], tuple[spec.Side, ...], tuple[spec.Severity, ...]]
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
        return self._tally()[0]

    @property
    def sides(self) -> tuple[spec.Side, ...]:
        """Whose fault each of ``codes`` is (docs/protocol.md "Violation codes"; aligned with ``codes``)."""
        return self._tally()[1]

    @property
    def errors(self) -> tuple[Violation, ...]:
        """The violations that break a rule (notices left out)."""
        return tuple(v for v in self.violations if v.is_error)

    @property
    def severities(self) -> tuple[spec.Severity, ...]:
        """The severity of each of ``codes`` (aligned with it): ``error`` when any of its violations is
        an error, else ``notice`` (``xac1_proto.rules``: the severity follows the rule's basis)."""
        return self._tally()[2]

    def _tally(self) -> _Tally:
        if not self.violations:
            return _NO_TALLY
        return _tally(tuple(map(_CODE_AND_SEVERITY, self.violations)), self.sender)


_NO_TALLY: Final = ((), (), ())
_CODE_AND_SEVERITY: Final = operator.attrgetter("code", "severity")  # a violation's (code, severity)
_SEVERITY: Final = operator.attrgetter("severity")


@functools.lru_cache(maxsize=1024)
def _tally(graded: tuple[tuple[spec.ViolationCode, spec.Severity], ...], sender: spec.Side) -> _Tally:
    """A verdict's codes (each once, in the order found), whose fault each is and its worst severity, from
    its violations' (code, severity) pairs and the sender: a pure function of few distinct inputs, so
    remembered (a misbehaving host repeats the same violations every exchange)."""
    worst: dict[spec.ViolationCode, spec.Severity] = {}
    for code, severity in graded:
        if worst.get(code) != spec.ERROR:
            worst[code] = severity
    codes = tuple(worst)
    return codes, tuple(side_of(code, sender) for code in codes), tuple(worst.values())


# a verdict (``_tuple_new(Verdict, fields)``), violation or the fact an answer teaches from its fields in
# order, as ``_make`` builds it but with no Python frame of its own (a NamedTuple's own ``__new__`` is a
# Python function; two verdicts an exchange, a fact most answers; every field is given)
_tuple_new: Final = tuple.__new__


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




# answers that neither count nor end the storm run: the alarm answer counts itself, the reset answer
# neither counts nor ends it, an unreadable line does neither
_KEEPS_STORM_RUN: Final = frozenset({None, _ALARM, _RESET})

# an alarm answer to the reset, by its code: the latch event (any other code: the reset refused)
_RESET_ALARM_EVENTS: Final = {spec.ALARM_ESTOP: LatchEvent.RESET_ESTOP,
                              spec.ALARM_NONE: LatchEvent.RESET_NOTHING}
# an alarm answer to another line, by its code, where the code alone decides
_CODE_EVENTS: Final = {spec.ALARM_ESTOP: LatchEvent.ESTOP, spec.ALARM_NONE: LatchEvent.NOTHING}

# what an alarm code itself makes unknown: after 0E nothing is stated of the position or the OUT ports;
# after a homing error, homed or not is learnt from 0RC ("Alarms")
_ALARM_FORGETS: Final[dict[int, tuple[str, ...]]] = {
    spec.ALARM_ESTOP: ("position", "outputs"),
    spec.ALARM_HOMING: ("homed", "position"),
}


def _latency(line: WaitingLine | None, t: float | None) -> float | None:
    """From ``line``'s last byte to ``t`` (an answer's first byte), when both are known."""
    if line is None or line.t_last is None or t is None:
        return None
    return t - line.t_last


def _is_error(violations: list[Violation]) -> bool:
    """Does any of ``violations`` break a rule (not a notice)?"""
    return spec.ERROR in map(_SEVERITY, violations)


class Conversation:
    """One conversation between a host and an XA-C1, judged event by event (see the module docstring).

    ``no_answer_timeout``: seconds after a line's last byte before silence is ``no-answer`` (moves get
    more); ``storm_limit``: ``0%%01`` answers in a row after which a host command is ``comm-error-storm``;
    ``speeds``: the speed table that prices a move's answer window; ``readings``: the severity of the
    rules that are our reading of a silent text (``notice``, the default, or ``error``: ``rules``);
    ``directions``: the lines the data holds (``both``, or one of ``host``, ``device``: module docstring).
    """

    def __init__(self, *, no_answer_timeout: float = spec.NO_ANSWER_TIMEOUT_S,
                 storm_limit: int = spec.STORM_LIMIT,
                 speeds: motion.SpeedTable = motion.DEFAULT_SPEEDS,
                 readings: rules.Readings = rules.DEFAULT_READINGS,
                 directions: Directions = BOTH) -> None:
        if no_answer_timeout <= 0 or storm_limit < 1:
            raise ValueError("no_answer_timeout must be > 0 and storm_limit >= 1")
        if readings not in rules.READINGS:
            raise ValueError(f"readings must be one of {', '.join(rules.READINGS)}, got {readings!r}")
        if directions not in DIRECTIONS:
            raise ValueError(f"directions must be one of {', '.join(DIRECTIONS)}, got {directions!r}")
        self.directions = directions
        self.one_way = directions != BOTH  # one line's bytes only: nothing pairs, latches or waits
        self.unanswerable = 0  # one way: host lines owed an answer the data cannot hold (counted, not kept)
        self.readings = readings
        self._severity = rules.severities(readings)
        self._regrade = readings != rules.DEFAULT_READINGS  # the decoder's violations graded again
        self._codes = {rule: row.code for rule, row in rules.RULES.items()}  # each rule's violation code
        self.no_answer_timeout = no_answer_timeout
        self.storm_limit = storm_limit
        self.speeds = speeds
        self.knowledge = Knowledge()
        self._queue = Waiting()
        self._motion: WaitingLine | None = None
        self._unreset_alarm = False  # an alarm answer came and no well-formed 0%C since
        self._reset_in_storm = False  # the last answer was 0%C00 to a reset sent at the storm limit
        self._next_i = 0
        self._last_t: float | None = None
        self._answer_began: float | None = None  # a device line began at this time and is still arriving
        self._cut: WaitingLine | None = None  # the line whose answer the end of the data cut
        self._cut_since: float | None = None  # when that cut answer began
        self._late: WaitingLine | None = None  # a move whose guessed window closed: its answer may come late

    def _v(self, rule: str, sentence: Callable[..., str], *values: object) -> Violation:
        """A conversation-level violation of ``rule`` (``rules.RULES``) under this conversation's
        readings; its sentence is ``sentence(*values)``, made only when shown."""
        return _tuple_new(Violation, (self._codes[rule], None, rule, self._severity[rule], None, sentence,
                                      values))

    def _regraded(self, reading: Reading) -> Reading:
        """The decoder's reading of a host line (``codec.read_frame``), graded under ``readings``."""
        violations = self._graded(reading.violations)
        return reading._replace(violations=violations,
                                error=reading.frame is None or any(v.is_error for v in violations))

    def _graded(self, violations: tuple[Violation, ...]) -> tuple[Violation, ...]:
        """The decoder's violations with their severity under ``readings`` (the decoder grades them by
        the default)."""
        if self.readings == rules.DEFAULT_READINGS or not violations:
            return violations
        sev = self._severity
        return tuple(v if v.severity == sev[v.rule] else v.graded(sev[v.rule]) for v in violations)

    # ---- what callers ask ----

    @property
    def waiting(self) -> bool:
        """Does a host line wait for its answer?"""
        return bool(self._queue)

    @property
    def expecting_answer(self) -> bool:
        """Does a well-formed command (not an error, not a line discarded during a move) wait?"""
        return self._motion is not None or any(w.kind == COMMAND for w in self._queue)

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

    def latch_state(self) -> LatchState:
        """Where the alarm latch stands (``latch.LatchState``), from what is known."""
        k = self.knowledge
        latched = k.latched.value
        if latched is None:
            return _FREE
        if latched != spec.ALARM_ESTOP:
            return _HELD
        if self._stop_known_pressed():
            return _STOP
        return _STOP_UNSEEN if k.under_stop.value is None else _STOP_UNSEEN_OVER

    def storm_state(self) -> StormState:
        """Where the host stands in a run of communication errors (``latch.StormState``)."""
        if self.knowledge.storm_run < self.storm_limit:
            return StormState.CALM
        return StormState.RECOVERING if self._reset_in_storm else StormState.STORM

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
        state = self.latch_state()
        k.stop_pressed = Fact(pressed, KNOWN)
        self._latch(state, LatchEvent.PRESS if pressed else LatchEvent.RELEASE, [], None, None)
        if pressed:
            k.latched = Fact(spec.ALARM_ESTOP, KNOWN)
            k.position, k.outputs = _NOT_KNOWN, _NOT_KNOWN  # nothing stated of the OUT ports across a stop
        elif unhomes and was_on:  # a release of a stop that was not on changes nothing
            k.homed, k.position = Fact(False, KNOWN), _NOT_KNOWN

    def move_finished(self, now: float) -> None:
        """A caller knows the move under way has ended: its answer is due within the plain timeout."""
        if self._motion is not None:
            self._queue.reschedule(self._motion, now + self.no_answer_timeout)

    # ---- events ----

    def host_frame(self, raw: bytes, t_first: float | None = None, t_last: float | None = None,
                   window: float | None = None) -> list[Verdict]:
        """A frame-shaped host line (from a frame start to LF). ``window``: how long the host will wait
        for its answer, when it says so (the client); else the engine's answer window."""
        # time passes to it (``tick``), but while no window can close before it (``Waiting.due``)
        out = self.tick(t_first, self._answer_began) if t_first is not None and self._queue.due < t_first \
            else []
        i = self._next_i
        self._next_i = i + 1
        if type(raw) is not bytes:
            raw = bytes(raw)
        reading = read_frame(raw, spec.COMMAND)
        if self._regrade:  # (the decoder grades by the default readings)
            reading = self._regraded(reading)
        frame, violations, header, error = reading
        found = [*violations]
        if self._unreset_alarm or self._reset_in_storm or self.knowledge.storm_run >= self.storm_limit:
            self._host_duties(header, error, found)
        if error:
            line = self._enqueue(i, ERROR, header, None, t_last, found, window)
        else:
            line = self._enqueue(i, COMMAND, header, frame, t_last, found, window, not violations)
        out.append(_tuple_new(Verdict, ("host-frame", HOST, i, raw, header, frame, tuple(found), None, None,
                                        t_first, t_last, line.waited_s)))
        return out

    def host_junk(self, raw: bytes, t_first: float | None = None, t_last: float | None = None,
                  window: float | None = None) -> list[Verdict]:
        """Host bytes that form no frame. A run ending in LF is a line the device must answer as an
        error (docs/protocol.md "Behaviour the vendor text states")."""
        out = self._time(t_first, self._answer_began)
        i = self._number()
        raw = bytes(raw)
        found = [_garbage(HOST, raw)]
        if raw.endswith(b"\n"):
            self._enqueue(i, ERROR, None, None, t_last, found, window, junk=True)
        out.append(Verdict("host-junk", HOST, i, raw, violations=tuple(found), t=t_first, t_last=t_last))
        return out

    def device_frame(self, raw: bytes, t_first: float | None = None,
                     t_last: float | None = None) -> list[Verdict]:
        """A frame-shaped device line: an answer. Its arrival passes time to ``t_first``: lines whose
        window closed before it began get ``no-answer`` (``tick``; an answer in time is in time)."""
        # time passes to it (``tick``: a line whose window closed before it began is closed), but while no
        # window can close before it (``Waiting.due``)
        out = self.tick(t_first, None) if t_first is not None and self._queue.due < t_first else []
        self._answer_began = None
        i = self._next_i
        self._next_i = i + 1
        raw = bytes(raw)  # (bytes themselves, not a copy)
        frame, violations, header, _error = read_frame(raw, spec.ANSWER)
        found = [*self._graded(violations)] if violations else []
        if self.one_way:  # no command can be in the data: only what the answer's own bytes show
            out.append(_tuple_new(Verdict, ("device-frame", DEVICE, i, raw, header, frame, tuple(found), None,
                                            None, t_first, t_last, None)))
            return out
        line, skipped = self._pair(header, t_first) if self._late is None \
            else self._late_or_pair(header, t_first, found)
        if skipped or line is None:
            out += self._mispaired(line, skipped, header, t_first, i, found)
        self._judge_answer(line, header, frame, found)
        out.append(_tuple_new(Verdict, ("device-frame", DEVICE, i, raw, header, frame, tuple(found),
                                        None if line is None else line.i, _latency(line, t_first), t_first,
                                        t_last, None)))
        return out

    def device_junk(self, raw: bytes, t_first: float | None = None, t_last: float | None = None,
                    line_ended: bool = False) -> list[Verdict]:
        """Device bytes that form no frame. A whole garbled line (ending in LF, or ``line_ended``: a
        partial line the device never finished) inside the head line's answer window is its garbled
        answer; bytes before a frame start are noise, never an answer."""
        out = self._time(t_first, t_first)
        self._answer_began = None
        i = self._number()
        raw = bytes(raw)
        line = None
        if (raw.endswith(b"\n") or line_ended) and self._head_answered_at(t_first):
            line = self._queue.popleft()
            self._end_motion(line)
            self._outcome_unknown(line)
        out.append(Verdict("device-junk", DEVICE, i, raw, violations=(_garbage(DEVICE, raw),),
                           reply_to=None if line is None else line.i, latency_s=_latency(line, t_first),
                           t=t_first, t_last=t_last))
        return out

    def tick(self, now: float, answer_since: float | None = None) -> list[Verdict]:
        """Time passes to ``now``: lines whose answer window closed get ``no-answer``. ``answer_since``:
        a device line began at this time and is still arriving (an answer that starts in time is in
        time). One comparison while no window can close (``Waiting.due``)."""
        last = self._last_t
        if last is None or now > last:
            self._last_t = now
        self._answer_began = answer_since
        if not self._queue.due < now:
            return []
        return self._expire(now, answer_since)

    def ended_inside_frame(self, sender: spec.Side, raw: bytes, t_first: float | None = None,
                           t_last: float | None = None) -> list[Verdict]:
        """The data ended inside a frame of ``sender`` (a capture file or a proxy stopped mid-line): the
        recording ended, not the sender, so no violation. Device bytes that began inside the head line's
        answer window are its answer, cut: that line is cut short at ``close()``, never ``no-answer``."""
        device = sender == DEVICE
        out = self._time(t_first, t_first if device else self._answer_began)
        i = self._number()
        reply_to = None
        if device and self._head_answered_at(t_first):
            head = self._queue.head
            assert head is not None
            self._cut, self._cut_since, reply_to = head, t_first, head.i
        out.append(Verdict("cut", sender, i, bytes(raw), reply_to=reply_to, t=t_first, t_last=t_last))
        return out

    def close(self, now: float | None = None) -> list[Verdict]:
        """End of the data: windows closed by ``now`` (default: the last time seen) give ``no-answer``;
        without time, every line still owed an answer does, but one whose answer the end cut
        (``ended_inside_frame``). Returns also the lines cut short (``waiting`` afterwards tells none is
        left)."""
        end = now if now is not None else self._last_t
        since = self._cut_since if self._cut is not None else None
        out = self._expire(end, since) if end is not None else []
        out += self._late_unanswered(None)
        self._answer_began = None
        keep: deque[WaitingLine] = deque()
        for w in self._queue:
            if w.deadline is None and w.owed and w is not self._cut:
                out.append(self._no_answer(w, None))
            elif w.owed:
                keep.append(w)
        self._queue.keep(keep)
        return out

    def host_gave_up(self, now: float | None = None) -> list[Verdict]:
        """The host stopped waiting (the client's timeout): every line still owed an answer is
        ``no-answer`` now."""
        out = self._late_unanswered(now)
        while self._queue:
            w = self._queue.popleft()
            self._end_motion(w)
            self._outcome_unknown(w)
            if w.owed:
                out.append(self._no_answer(w, now))
        return out

    def cut_short(self) -> int:
        """Lines still owed an answer whose window had not closed when the data ended, and (one way) those
        whose answer the data cannot hold; forgets them."""
        n = sum(1 for w in self._queue if w.owed) + self.unanswerable
        self.unanswerable = 0
        self._queue.clear()
        self._motion = None
        return n

    # ---- pairing ----

    def _number(self) -> int:
        i = self._next_i
        self._next_i += 1
        return i

    def _time(self, t: float | None, since: float | None) -> list[Verdict]:
        return [] if t is None else self.tick(t, since)

    def _head_answered_at(self, t: float | None) -> bool:
        """Do device bytes that began at ``t`` answer the head line (one not discarded, in its window)?"""
        head = self._queue.head
        return head is not None and head.kind != DISCARD and self._queue.open_at(head, t)

    def _enqueue(self, i: int, kind: str, header: str | None, frame: Frame | None, t_last: float | None,
                 found: list[Violation], window: float | None = None, plain: bool = False,
                 junk: bool = False) -> WaitingLine:
        """Queue a host line, judging when it was sent (docs/protocol.md "Framing": strict request/answer);
        a well-formed move sent while nothing is latched is the move under way."""
        overlapped = False
        if self._motion is not None or self._queue:
            kind, overlapped = self._sent_while_waiting(kind, header, t_last, found)
        move = frame if kind == COMMAND and header in spec.MOVE_HEADERS else None
        waited_s, guessed = self._window_for(move, window)
        line = WaitingLine(i, kind, header, frame, t_last, waited_s, overlapped, move is not None, plain,
                           junk, guessed)
        if self.one_way:  # its answer cannot be in the data: counted, not kept
            self.unanswerable += 1
            return line
        self._queue.append(line)
        if move is not None and not overlapped and self.knowledge.latched.value is None:
            self._motion = line
        return line

    def _window_for(self, move: Frame | None, window: float | None) -> tuple[float, bool]:
        """A line's answer window, and whether it rests on the guessed speed table: ``window`` when the
        host says how long it waits (the client), a move's (``answer_window``), else the timeout."""
        if window is not None:
            return window, False
        if move is None:
            return self.no_answer_timeout, False
        return self.answer_window(move), self.speeds.guessed

    def _sent_while_waiting(self, kind: str, header: str | None, t_last: float | None,
                            found: list[Violation]) -> tuple[str, bool]:
        """A host line sent while a move's answer or another line's is awaited: its kind (discarded during
        a move) and whether it overlaps a line owed an answer."""
        if self._motion is not None:
            found.append(self._v("command-during-motion", sentences.command_during_motion, header,
                                 self._motion.header, self._motion.i))
            return DISCARD, False
        first = next((w for w in self._queue if w.owed), None)
        if first is None:
            return kind, False
        found.append(self._v("overlapping-command", sentences.overlapping_command, header, first.header,
                             first.i, first.t_last is None and t_last is None))
        return kind, True

    def _pair(self, header: str | None, t: float | None) -> tuple[WaitingLine | None,
                                                                  list[WaitingLine] | tuple[()]]:
        """The line an answer belongs to, and the lines it shows were skipped (module docstring): the
        first line of its header sent before the answer began (a line discarded during a move only when
        it alone waits); the usual answer is the head's, nothing skipped."""
        if header is None or header == _ALARM:  # fits any line: no line's own
            return self._pair_past(None, header)
        queue = self._queue
        line = queue.take_own_answer(header, t)
        if line is not None:
            if line is self._motion:
                self._motion = None
            return line, _NOTHING_SKIPPED
        return self._pair_past(self._line_of(header, t) if queue else None, header)

    def _mispaired(self, line: WaitingLine | None, skipped: list[WaitingLine] | tuple[()], header: str | None,
                   t: float | None, i: int, found: list[Violation]) -> list[Verdict]:
        """What answer ``i``'s pairing shows went wrong: ``no-answer`` for each line it skipped that was
        owed an answer; ``unsolicited-answer`` (into ``found``) when it pairs with no line."""
        if line is None:
            found.append(self._v("unsolicited-answer", sentences.unsolicited_answer, header))
        return [self._no_answer(w, t, skipped_by=i) for w in skipped if w.owed]

    def _line_of(self, header: str, t: float | None) -> WaitingLine | None:
        """The first waiting line of ``header`` sent before ``t`` (a discarded one only when alone)."""
        alone = len(self._queue) == 1
        for w in self._queue:
            if w.header == header and (t is None or w.t_last is None or w.t_last <= t) \
                    and (alone or w.kind != DISCARD):
                return w
        return None

    def _first_fitting(self, header: str | None) -> WaitingLine | None:
        """The first line an answer of ``header`` that is no line's own fits: one not discarded during a
        move (a discarded one only when it alone waits and the answer fits it; an alarm fits any)."""
        alone = len(self._queue) == 1
        for w in self._queue:
            fits = header == _ALARM or (w.header is not None and w.header == header)
            if w.kind != DISCARD or (alone and fits):
                return w
        return None

    def _pair_past(self, chosen: WaitingLine | None, header: str | None) -> tuple[WaitingLine | None,
                                                                                    list[WaitingLine]]:
        """``_pair`` when the answer is not the head's: ``chosen``, the line of its header, else the first
        line it fits; the lines before it were skipped."""
        if chosen is None:
            chosen = self._first_fitting(header)
        skipped: list[WaitingLine] = []
        while self._queue:
            w = self._queue.popleft()
            self._end_motion(w)
            if w is chosen:
                return w, skipped
            skipped.append(w)
            self._outcome_unknown(w)
        return None, skipped

    def _end_motion(self, w: WaitingLine) -> None:
        if self._motion is w:
            self._motion = None

    def _expire(self, now: float, since: float | None) -> list[Verdict]:
        """``no-answer`` for each line whose window closed by ``now`` (``Waiting.closed``; ``since``: an
        answer began then and is still arriving)."""
        out: list[Verdict] = []
        for w in self._queue.closed(now, since):
            self._end_motion(w)
            self._outcome_unknown(w)
            if w.owed and w.guessed:  # its answer may yet come: judged when it does, or when it cannot
                out += self._late_unanswered(None)
                self._late = w
            elif w.owed:
                out.append(self._no_answer(w, w.deadline))
        return out

    def _late_unanswered(self, t: float | None) -> list[Verdict]:
        """The late move (``_late``), if any, got no answer after all: its ``no-answer`` (at ``t``;
        None: when its window closed)."""
        late, self._late = self._late, None
        if late is None:
            return []
        return [self._no_answer(late, late.deadline if t is None else t)]

    def _late_or_pair(self, header: str | None, t: float | None,
                      found: list[Violation]) -> tuple[WaitingLine | None, list[WaitingLine] | tuple[()]]:
        """``_pair`` while a move whose window rested on the guessed speed table waits late (``_late``):
        an answer of its header that no waiting line claims is its answer, late (``late-move-answer``, a
        notice: silent items 15, 17); any other answer shows it got none (``no-answer``)."""
        late, self._late = self._late, None
        assert late is not None
        if header is not None and header == late.header and self._line_of(header, t) is None:
            found.append(self._v("late-move-answer", sentences.late_move_answer, late.header, late.i,
                                 _latency(late, t), late.waited_s))
            return late, _NOTHING_SKIPPED
        line, skipped = self._pair(header, t)
        return line, [late, *skipped]

    def _no_answer(self, w: WaitingLine, t: float | None, skipped_by: int | None = None) -> Verdict:
        rule = "no-answer-junk" if w.junk else "no-answer-error" if w.kind == ERROR else "no-answer"
        waited = None if t is None else w.waited_s
        violation = self._v(rule, sentences.no_answer, w.header, w.i, w.kind == ERROR, skipped_by, waited)
        return Verdict("no-answer", HOST, None, header=w.header, violations=(violation,), reply_to=w.i,
                       t=t, waited_s=waited)

    # ---- host duties ----

    def _host_duties(self, header: str | None, error: bool, found: list[Violation]) -> None:
        """Storm and alarm-ignored (docs/protocol.md "Behaviour the vendor text states": host duty,
        latched alarm), into ``found``: the storm run's table (``latch.HOST_DUTY``; below the storm limit
        the state is calm, whose cells name no duty) and the reset owed."""
        k = self.knowledge
        good_reset = header == spec.RESET_HEADER and not error
        duty = HOST_DUTY[(self.storm_state(), good_reset)] if k.storm_run >= self.storm_limit else None
        if duty == "storm-recovery":
            found.append(self._v(duty, sentences.storm_recovery, header, k.storm_run, good_reset))
        elif duty == "comm-error-storm":
            found.append(self._v(duty, sentences.comm_error_storm, header, k.storm_run, self.storm_limit))
        self._reset_in_storm = False
        if self._unreset_alarm and not good_reset:
            found.append(self._v("alarm-ignored", sentences.alarm_ignored, header))
        if good_reset:
            self._unreset_alarm = False

    # ---- the answer's rules ----

    def _judge_answer(self, line: WaitingLine | None, header: str | None, frame: Frame | None,
                      found: list[Violation]) -> None:
        """The rules of an answer to ``line`` (None: unsolicited). The storm run (host duty): ``0%%01``
        answers count, the reset answer neither counts nor ends it, any other answer ends it, a faulty one
        too; an unreadable line (or alarm code) does neither."""
        if header == _ALARM and frame is not None:
            self._alarm(line, frame.code, found)  # type: ignore[attr-defined]
            return
        if header not in _KEEPS_STORM_RUN:
            self.knowledge.storm_run = 0
        if line is None:  # (unsolicited: nothing it says is trusted)
            return
        if frame is None or header is None:
            self._outcome_unknown(line)
        elif line.kind == ERROR:
            found.append(self._v("error-accepted", sentences.error_accepted, header, line.header, line.i))
            self._outcome_unknown(line)
        elif line.is_reset:
            self._reset_answered(line, header, frame, found)
        else:
            self._normal_answer(line, header, frame, found)

    def _normal_answer(self, line: WaitingLine, header: str, frame: Frame, found: list[Violation]) -> None:
        """A normal answer to a well-formed command: the latch, the pairing, then what a clean exchange
        establishes (judged against the mode before it; silent item 11: communicating gives mode 1)."""
        k = self.knowledge
        if k.latched.value is not None or k.stop_cleared.value is not None:  # else the latch has nothing
            self._latch(self.latch_state(), _NORMAL, found, line, None)  # to say (FREE: no rule)
        command = line.frame
        if command is not None and self._pairing(line, command, header, frame, found) \
                and not (found and _is_error(found)):
            learn = _LEARN[header]
            if learn is not None:
                learn(self, command, frame, found)
            if header != _SWITCH_MODE:
                k.mode = _MODE_1
        else:
            self._outcome_unknown(line)

    def _reset_answered(self, line: WaitingLine, header: str, frame: Frame, found: list[Violation]) -> None:
        """The reset (0%C) answered normally: 0%C00 clears the latch (``latch.LATCH``); another command's
        answer is answer-mismatch and what the reset did is unknown."""
        if header != _RESET:
            self._latch(self.latch_state(), LatchEvent.RESET_MISMATCHED, found, line, None)
            self._pairing(line, line.frame, header, frame, found)  # type: ignore[arg-type]
            self._outcome_unknown(line)
            return
        k = self.knowledge
        k.mode = _MODE_1  # silent item 11: communicating gives mode 1
        self._reset_in_storm = k.storm_run >= self.storm_limit
        pressed = LatchEvent.RESET_DONE_PRESSED if self._stop_known_pressed() else LatchEvent.RESET_DONE
        self._latch(self.latch_state(), pressed, found, line, None)

    def _alarm(self, line: WaitingLine | None, code: int, found: list[Violation]) -> None:
        """An alarm answer: the storm run counts ``0%%01``; the latch's table judges and moves
        (``latch.LATCH``); the code latches (00 latches nothing, silent item 12); a refused command takes
        no effect (item 18), but a move may have stopped anywhere."""
        k = self.knowledge
        k.storm_run = k.storm_run + 1 if code == spec.ALARM_COMM else 0
        event = self._alarm_event(line, code)
        self._latch(self.latch_state(), event, found, line, code)
        kind = ALARM_EVENTS[event]
        if kind.latches:
            k.latched = _tuple_new(Fact, (code, LEARNT if k.latched.status == UNKNOWN else k.latched.status))
        if kind.owes_reset:
            self._unreset_alarm = True
        for name in _ALARM_FORGETS.get(code, ()):
            setattr(k, name, _NOT_KNOWN)
        if line is not None:
            self._refused(line)

    def _alarm_event(self, line: WaitingLine | None, code: int) -> LatchEvent:
        """What an alarm answer with ``code`` to ``line`` is to the latch (``latch.LatchEvent``)."""
        if line is not None and line.is_reset:
            return _RESET_ALARM_EVENTS.get(code, LatchEvent.RESET_REFUSED)
        event = _CODE_EVENTS.get(code)
        if event is not None:
            return event
        k = self.knowledge
        if line is not None and line.harmless and code == k.stop_cleared.value:
            return LatchEvent.CLEARED_BACK
        return _SAME if code == k.latched.value else _OTHER

    def _latch(self, state: LatchState, event: LatchEvent, found: list[Violation], line: WaitingLine | None,
               code: int | None) -> None:
        """Look ``(state, event)`` up in ``latch.LATCH``: record the rule it breaks, apply its effect."""
        rule, effect = _LATCH_CELLS[state][event]
        if rule is not None:
            found.append(self._latch_violation(rule, line, code))
        if effect is not None:
            effect(self.knowledge)

    def _latch_violation(self, rule: str, line: WaitingLine | None, code: int | None) -> Violation:
        """The violation of a latch rule, with the values its sentence needs."""
        k = self.knowledge
        header, i = (None, 0) if line is None else (line.header, line.i)
        if rule == "stop-alarm-back":
            if code is None:  # a normal answer: the alarm held under the stop is lost
                return self._v(rule, sentences.held_alarm_lost, header, k.under_stop.value)
            return self._v(rule, sentences.cleared_alarm_back, header, i, code)
        if rule == "latch-broken":
            return self._v(rule, sentences.latch_broken, header, k.latched.value)
        if rule == "latch-code-changed":
            return self._v(rule, sentences.latch_code_changed, k.latched.value, code)
        if rule == "reset-refused":
            return self._v(rule, sentences.reset_refused, header, i, code)
        return self._v(rule, sentences.estop_cleared)

    def _refused(self, line: WaitingLine) -> None:
        """``line`` was answered with an alarm: it took no effect (silent item 18), but a move may have
        stopped anywhere (item 19) and may have homed first ("Alarms": homing after each alarm)."""
        k = self.knowledge
        k.mode = _MODE_1  # silent item 11: a refused line is communication too
        self._end_motion(line)
        if line.is_move:
            k.position = _NOT_KNOWN
            if k.homed.value is not True:
                k.homed = _NOT_KNOWN

    def _stop_known_pressed(self) -> bool:
        k = self.knowledge
        return k.stop_pressed.value is True and k.stop_pressed.status == KNOWN

    def _pairing(self, line: WaitingLine, cmd: Frame, header: str, frame: Frame,
                 found: list[Violation]) -> bool:
        """Answer-mismatch and echo-mismatch (docs/protocol.md "Frames"; echoes judged by fields, never
        bytes) of the answer ``frame`` to ``line``'s command ``cmd``. True when the answer fits it."""
        if header != line.header:
            found.append(self._v("answer-mismatch", sentences.answer_mismatch, header, line.header, line.i))
            return False
        if header in _ECHOED:
            if tuple.__ne__(frame, cmd):
                found.append(self._v("echo-mismatch", sentences.echo_mismatch, header, line.header, line.i,
                                     frame, cmd))
                return False
        elif header in _BOTH_N and frame.n != cmd.n:  # type: ignore[attr-defined]
            found.append(self._v("answer-mismatch", sentences.answer_for_other_n, header,
                                 frame.n, line.header, line.i, cmd.n))  # type: ignore[attr-defined]
            return False
        return True

    # ---- knowledge and read-back ----

    def _readback(self, found: list[Violation], what: str, seen: object, fact: Fact[T], how: str,
                  rule: str = "readback-mismatch") -> None:
        found.append(self._v(rule, sentences.readback, what, seen, fact.status == KNOWN, how))

    def _on_switch_mode(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0CM: the mode sent; after 0CM0 the external I/O owns the controller until the next line."""
        k = self.knowledge
        mode = c.mode  # type: ignore[attr-defined]
        k.mode = _tuple_new(Fact, (mode, KNOWN))
        if mode == 0:  # silent item 11
            k.outputs, k.position = _NOT_KNOWN, _NOT_KNOWN
            if k.homed.value is not True:
                k.homed = _NOT_KNOWN

    def _on_write_point(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0WP: the point is what was written."""
        k = self.knowledge
        k.points[c.n] = _tuple_new(Fact, (PointData(c.v, c.a, c.o, c.pos), KNOWN))  # type: ignore[attr-defined]

    def _on_store_current(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0WC: the point stored at the position (V, A, O learnt: silent item 4)."""
        k = self.knowledge
        assert isinstance(a, StoreCurrentAnswer)
        pos = k.position
        if pos.status != UNKNOWN and a.pos != pos.value:
            self._readback(found, f"0WC{a.n:X}'s Pos", f"{a.pos:06X}", pos,
                           f"the axis at {pos.value:06X}", "readback-position")
        k.points[a.n] = _tuple_new(Fact, (PointData(a.v, a.a, a.o, a.pos), LEARNT))

    def _on_move_point(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0MP: homed; at the point (as known as the point); the OUT ports unknown after 0MP N (item 8)."""
        k = self.knowledge
        assert isinstance(c, MovePoint)
        k.homed = _HOMED
        point = k.point(c.n)
        if c.n and point.value is not None:
            k.position = _tuple_new(Fact, (point.value.pos, point.status))
        else:  # homing, or a point not known: where the answer says the axis is (item 7), learnt
            k.position = _tuple_new(Fact, (a.pos, LEARNT))  # type: ignore[attr-defined]
        if c.n:
            k.outputs = _NOT_KNOWN  # silent item 8

    def _on_move_direct(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0MV: homed, at the position sent."""
        k = self.knowledge
        k.homed, k.position = _HOMED, _tuple_new(Fact, (c.pos, KNOWN))  # type: ignore[attr-defined]

    def _on_read_outputs(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0RS: the OUT ports read back."""
        k = self.knowledge
        o = a.o  # type: ignore[attr-defined]
        if k.outputs.status != UNKNOWN and o != k.outputs.value:
            self._readback(found, "0RS's O", o, k.outputs, f"O={k.outputs.value}", "readback-outputs")
        elif k.outputs != (o, LEARNT):
            k.outputs = _tuple_new(Fact, (o, LEARNT))

    def _on_write_outputs(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0WS: the OUT ports are what was written."""
        k = self.knowledge
        if k.outputs != (c.o, KNOWN):  # type: ignore[attr-defined]
            k.outputs = _tuple_new(Fact, (c.o, KNOWN))  # type: ignore[attr-defined]

    def _on_read_version(self, c: Frame, a: Frame, found: list[Violation]) -> None:
        """0RV: the version read back."""
        k = self.knowledge
        version = a.version  # type: ignore[attr-defined]
        if k.version.status != UNKNOWN and version != k.version.value:
            self._readback(found, "0RV", version, k.version, f"version {k.version.value}",
                           "readback-version")
        else:
            k.version = _tuple_new(Fact, (version, LEARNT))

    def _on_read_point(self, c: Frame, a: ReadPointAnswer, found: list[Violation]) -> None:
        """0RP: the point read back (against what was written or read before)."""
        k = self.knowledge
        seen = PointData(a.v, a.a, a.o, a.pos)
        fact = k.point(a.n)
        if fact.value is not None and seen != fact.value:
            self._readback(found, f"point {a.n:X}", seen.show(), fact, fact.value.show())
        elif fact.value is None:
            k.points[a.n] = _tuple_new(Fact, (seen, LEARNT))

    def _on_read_current(self, c: Frame, a: ReadCurrentAnswer, found: list[Violation]) -> None:
        """0RC: before homing N, V, A 0 and Pos FFFFFF (vendor §7 (3), whatever else is known); a homed
        position while the axis is known not homed only where the mode is known 1 throughout (in mode 0,
        after a power-on or an unseen power cycle, the external I/O may home it: §7 (10), silent item 11);
        after a move, where the move went."""
        if self._unhomed_judged(a, found):
            return
        k = self.knowledge
        if a.pos == spec.UNKNOWN_POSITION:  # the device states it is not homed: learnt, never judged (an
            k.homed, k.position = _tuple_new(Fact, (False, LEARNT)), _NOT_KNOWN  # unseen power cycle...)
            k.outputs = _NOT_KNOWN  # nothing is stated of the OUT ports across a power cycle
        elif k.position.status != UNKNOWN and a.pos != k.position.value:
            self._readback(found, "0RC's Pos", f"{a.pos:06X}", k.position,
                           f"the axis at {k.position.value:06X}", "readback-position")
        else:
            if k.homed.value is not True:
                k.homed = _tuple_new(Fact, (True, LEARNT))
            if k.position.status == UNKNOWN:
                k.position = _tuple_new(Fact, (a.pos, LEARNT))

    def _unhomed_judged(self, a: ReadCurrentAnswer, found: list[Violation]) -> bool:
        """readback-unhomed of a 0RC answer: FFFFFF with N, V or A not 0; a homed position while the axis
        is known not homed in mode 1. True when found."""
        k = self.knowledge
        unknown = a.pos == spec.UNKNOWN_POSITION
        if unknown and (a.n, a.v, a.a) != (0, 0, 0):
            self._readback(found, "0RC", _shown(a), Fact(False, KNOWN),
                           "Pos FFFFFF, which comes with N, V, A 0", "readback-unhomed")
            return True
        if k.homed.value is False and k.homed.status == KNOWN and k.mode == _MODE_1 and not unknown:
            self._readback(found, "0RC", _shown(a), k.homed,
                           "the axis not homed (0RC then answers N, V, A 0 and Pos FFFFFF)",
                           "readback-unhomed")
            return True
        return False

    def _outcome_unknown(self, line: WaitingLine) -> None:
        """A line whose answer is missing, garbled or faulty: what it would change is unknown now (the
        ``forget`` column of its header's row)."""
        c = line.frame
        if c is not None:  # (a frame's line has its header)
            _FORGET[line.header](self.knowledge, c, line.kind == COMMAND)

    # ---- move time (silent items 15, 17) ----

    def move_time(self, command: Frame) -> float:
        """Seconds a move (0MP/0MV) may take at worst, homing included; 0 for other commands. Whatever is
        unknown is taken at its worst: an axis not homed homes from the far end of the stroke first; a
        homed axis at an unknown position starts as far from the target as the stroke allows; an unknown
        homing is the worse of the two; an unknown point is as far away as the stroke allows at the
        slowest speed."""
        leg = self._leg(command)
        if leg is None:
            return 0.0
        target, pps, accel = leg
        k, s = self.knowledge, self.speeds
        homed = k.homed.value
        if homed is not False and k.position.value is not None:
            start = k.position.value
            return motion.move_time(_far_from(start) if target is None else target - start, pps, accel)
        homing = motion.move_time(STROKE_END, s.homing_pps, s.homing_accel)
        via_home = homing + motion.move_time(STROKE_END if target is None else target, pps, accel)
        if homed is False:
            return via_home
        from_anywhere = motion.move_time(STROKE_END if target is None else _far_from(target), pps, accel)
        return from_anywhere if homed is True else max(via_home, from_anywhere)

    def _leg(self, command: Frame) -> tuple[int | None, float, int] | None:
        """A move's target (None: an unknown point), speed and acceleration; None for other commands."""
        s = self.speeds
        if isinstance(command, MoveDirect):
            return command.pos, s.direct_speed(command.vel), command.a
        if not isinstance(command, MovePoint):
            return None
        if command.n == 0:
            return 0, s.homing_pps, s.homing_accel
        point = self.knowledge.point(command.n).value
        if point is None:
            return None, s.point_speed(1), 1
        return point.pos, s.point_speed(point.v), point.a


def _far_from(pos: int) -> int:
    """The longest distance a move from (or to) ``pos`` can cover within the stroke."""
    return max(pos, STROKE_END - pos)


def _shown(a: ReadCurrentAnswer) -> str:
    """A 0RC answer's fields as a read-back sentence shows them (made only for a violation)."""
    return f"N={a.n:X} V={a.v} A={a.a} Pos={a.pos:06X}"


_MODE_1: Final = Fact(1, KNOWN)
_HOMED: Final = Fact(True, KNOWN)


def _garbage(side: spec.Side, raw: bytes) -> Violation:
    """Junk: bytes that form no frame (docs/protocol.md "Framing"); its sentence made when shown."""
    return Violation.said("garbage", "garbage", rules.severity("garbage"), sentences.garbage, side, raw,
                          offset=0)


# ---- the latch's effects (``latch.Effect``), each on what the conversation knows ----

def _stop_over(k: Knowledge) -> None:
    k.under_stop, k.stop_cleared = k.latched, Fact(None, KNOWN)


def _stop_over_reset(k: Knowledge) -> None:
    k.stop_cleared, k.under_stop = k.latched, Fact(None, KNOWN)


def _clear_under_stop(k: Knowledge) -> None:
    k.stop_cleared, k.under_stop = k.under_stop, Fact(None, KNOWN)  # vendor §6


def _new_alarm(k: Knowledge) -> None:
    k.stop_cleared = _NOT_KNOWN


def _forget_stop(k: Knowledge) -> None:
    k.under_stop, k.stop_cleared = _NOT_KNOWN, _NOT_KNOWN


def _forget_cleared(k: Knowledge) -> None:
    if k.stop_cleared.value is not None:
        k.stop_cleared = _NOT_KNOWN


def _cleared(k: Knowledge) -> None:
    k.latched = Fact(None, KNOWN)
    k.under_stop, k.stop_cleared = _NOT_KNOWN, _NOT_KNOWN


def _released(k: Knowledge) -> None:
    _cleared(k)
    k.homed, k.position = _NOT_KNOWN, _NOT_KNOWN  # what the axis does after the release: item 3


def _release(k: Knowledge) -> None:
    k.latched = k.under_stop if k.under_stop.value is not None else Fact(None, KNOWN)
    k.under_stop = _NOT_KNOWN


_LATCH_EFFECTS: Final[dict[Effect, Callable[[Knowledge], None] | None]] = {
    Effect.KEEP: None,  # (nothing to apply)
    Effect.STOP_OVER: _stop_over,
    Effect.STOP_OVER_RESET: _stop_over_reset,
    Effect.CLEAR_UNDER_STOP: _clear_under_stop,
    Effect.NEW_ALARM: _new_alarm,
    Effect.FORGET_STOP: _forget_stop,
    Effect.FORGET_CLEARED: _forget_cleared,
    Effect.CLEARED: _cleared,
    Effect.CLEARED_RELEASED: _released,
    Effect.RELEASED: _released,
    Effect.RELEASE: _release,
}
assert set(_LATCH_EFFECTS) == set(Effect), "every effect is applied"
# ``latch.LATCH`` with each effect's function, by state then event (two look-ups of members hashed by
# identity, no key tuple to make)
_LatchCell = tuple[str | None, Callable[[Knowledge], None] | None]  # the rule broken, the effect applied
_LATCH_CELLS: Final[dict[LatchState, dict[LatchEvent, _LatchCell]]] = {
    state: {event: (cell.rule, _LATCH_EFFECTS[cell.effect])
            for (in_state, event), cell in LATCH.items() if in_state is state}
    for state in LatchState}


# ---- what a failed exchange forgets (the ``forget`` column) ----

def _forgets_nothing(k: Knowledge, c: Frame, sent: bool) -> None:
    """A read: it changes nothing."""


def _forget_point(k: Knowledge, c: Frame, sent: bool) -> None:
    """0WP, 0WC: the point written or stored is unknown."""
    k.points.pop(c.n, None)  # type: ignore[attr-defined]


def _forget_outputs(k: Knowledge, c: Frame, sent: bool) -> None:
    """0WS: the OUT ports are unknown."""
    k.outputs = _NOT_KNOWN


def _forget_move(k: Knowledge, c: Frame, sent: bool) -> None:
    """0MP, 0MV: the axis may be anywhere, homed or not (unless known homed); after 0MP N the OUT ports
    are unknown too (silent item 8)."""
    k.position = _NOT_KNOWN
    if k.homed.value is not True:
        k.homed = _NOT_KNOWN
    if isinstance(c, MovePoint) and c.n:
        k.outputs = _NOT_KNOWN


def _forget_mode(k: Knowledge, c: Frame, sent: bool) -> None:
    """0CM: the mode is unknown."""
    k.mode = _NOT_KNOWN


def _forget_latch(k: Knowledge, c: Frame, sent: bool) -> None:
    """0%C sent as a command (not discarded during a move): the latch is unknown."""
    if sent:
        k.latched = _NOT_KNOWN


class HeaderRules(NamedTuple):
    """One row a command header: what a clean exchange teaches (``learn``, a method of ``Conversation``
    taking the command, the answer and the violations found; None: nothing but the mode) and what a
    failed one forgets (``forget``: the knowledge, the command, whether it was sent as a command)."""

    learn: Callable[..., None] | None
    forget: Callable[[Knowledge, Frame, bool], None]


# one row a command header of spec.FRAME_SPECS (a test checks every header has its row)
HEADER_RULES: Final[dict[str, HeaderRules]] = {
    ReadPoint.HEADER: HeaderRules(Conversation._on_read_point, _forgets_nothing),
    WritePoint.HEADER: HeaderRules(Conversation._on_write_point, _forget_point),
    ReadCurrent.HEADER: HeaderRules(Conversation._on_read_current, _forgets_nothing),
    StoreCurrent.HEADER: HeaderRules(Conversation._on_store_current, _forget_point),
    MovePoint.HEADER: HeaderRules(Conversation._on_move_point, _forget_move),
    MoveDirect.HEADER: HeaderRules(Conversation._on_move_direct, _forget_move),
    ReadOutputs.HEADER: HeaderRules(Conversation._on_read_outputs, _forgets_nothing),
    WriteOutputs.HEADER: HeaderRules(Conversation._on_write_outputs, _forget_outputs),
    ReadVersion.HEADER: HeaderRules(Conversation._on_read_version, _forgets_nothing),
    SwitchMode.HEADER: HeaderRules(Conversation._on_switch_mode, _forget_mode),
    AlarmReset.HEADER: HeaderRules(None, _forget_latch),  # the latch: ``latch.LATCH``
}
assert set(HEADER_RULES) == {fs.header for fs in spec.FRAME_SPECS if fs.role == spec.COMMAND}, \
    "every command header has its row"
# its columns, each one look-up an exchange (a row's field read off its NamedTuple is an attribute
# look-up through a descriptor)
_LEARN: Final[dict[str, Callable[..., None] | None]] = {
    header: row.learn for header, row in HEADER_RULES.items()}
_FORGET: Final[dict[str | None, Callable[[Knowledge, Frame, bool], None]]] = {
    header: row.forget for header, row in HEADER_RULES.items()}


__all__ = ["HEADER_RULES", "Conversation", "Fact", "HeaderRules", "Knowledge", "PointData", "Verdict",
           "header_of", "side_of", "KNOWN", "LEARNT", "UNKNOWN"]
