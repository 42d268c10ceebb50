"""The alarm latch, the emergency stop, the reset and the storm run as declared state machines
(docs/protocol.md "Behaviour the vendor text states": latched alarm, alarm reset, host duty; silent items
3, 12 and 22).

How this works (the shape of h11's ``_state.py``): the latch is always in one of the few ``LatchState``s,
read from what the conversation knows (the engine's ``latch_state``); what the line or a caller shows of
it is one of the closed set of ``LatchEvent``s. ``LATCH[(state, event)]`` is the row of the rulebook
(``rules.RULE_ROWS``) the event breaks in that state (None: none) and the ``Effect`` it has on the
latch's memory: the alarm held under an emergency stop, the alarm a reset cleared during one. Every pair
has its cell, so nothing is decided outside the table. The storm run is the same kind of table
(``StormState``, ``HOST_DUTY``): what a host line breaks, from the run and whether it is the reset.
Nothing here holds state, reads a clock or does I/O: the engine (``conversation``) classifies, looks up
and applies.
"""

from __future__ import annotations

from enum import Enum
from typing import Final, NamedTuple


class LatchState(Enum):
    """Where the alarm latch stands."""

    __hash__ = object.__hash__  # members are unique: hashed by identity, as they compare

    FREE = "nothing latched (or the latch unknown: nothing to repeat)"
    HELD = "an alarm other than emergency stop (0E) latched"
    STOP = "0E latched, the stop input known pressed"
    STOP_UNSEEN = "0E latched, the stop input not known pressed: it may have been released unseen"
    STOP_UNSEEN_OVER = "as STOP_UNSEEN, with an alarm known held under the stop until a reset"


class LatchEvent(Enum):
    """What happens to the latch: an answer to a host line, or the stop input a caller drives."""

    __hash__ = object.__hash__  # members are unique: hashed by identity, as they compare

    NORMAL = "a normal answer to a command other than the reset"
    RESET_DONE = "the reset (0%C) answered 0%C00"
    RESET_DONE_PRESSED = "the reset answered 0%C00 while the stop input is known pressed"
    RESET_MISMATCHED = "the reset answered with another command's answer (answer-mismatch)"
    ESTOP = "alarm 0E to a command"
    SAME = "the latched alarm repeated"
    OTHER = "an alarm with another code than the latched one"
    NOTHING = "alarm 00: an alarm answer that latches nothing (silent item 12)"
    CLEARED_BACK = ("the alarm the reset cleared during the stop, answering a plain command that raises no "
                    "alarm of its own")
    RESET_ESTOP = "the reset answered 0E"
    RESET_REFUSED = "the reset answered another alarm"
    RESET_NOTHING = "the reset answered alarm 00"
    PRESS = "the stop input pressed (a caller that drives it)"
    RELEASE = "the stop input released (a caller that drives it)"


class Effect(Enum):
    """What an event does to the latch's memory (the engine's ``Knowledge``)."""

    __hash__ = object.__hash__  # members are unique: hashed by identity, as they compare

    KEEP = "nothing"
    STOP_OVER = "the latched alarm is held under the stop until a reset"
    STOP_OVER_RESET = "0E came with the reset: the latched alarm is the one the reset cleared"
    CLEAR_UNDER_STOP = "the reset during the stop cleared the alarm held under it (vendor §6)"
    NEW_ALARM = "a new alarm latched: what a reset cleared during a stop is history"
    FORGET_STOP = "the stop was released unseen: what was held or cleared under it is forgotten"
    FORGET_CLEARED = "answered normally: the alarm the reset cleared did not come back"
    CLEARED = "the reset cleared the latch"
    CLEARED_RELEASED = "the reset cleared the latch after a release unseen: homing is unknown (item 3)"
    RELEASED = "the stop was released unseen: the latch clears, homing is unknown (item 3)"
    RELEASE = "the stop input released: an alarm held under it is latched again"


class Transition(NamedTuple):
    """A cell of ``LATCH``: the rule broken (a name of ``rules.RULES``; None: none) and the effect."""

    rule: str | None
    effect: Effect


class EventKind(NamedTuple):
    """Of an alarm event: does its code latch (every alarm answer but 00 and 0E to a stop already on),
    and does it leave the host owing a reset (an alarm answer to anything but the reset)?"""

    latches: bool
    owes_reset: bool


E, S = LatchEvent, LatchState
_K = Effect

# the events every state shares, then each state's own cells
_ALARMS: Final[dict[LatchEvent, Transition]] = {
    E.ESTOP: Transition(None, _K.STOP_OVER),
    E.SAME: Transition(None, _K.NEW_ALARM),
    E.OTHER: Transition(None, _K.NEW_ALARM),
    E.NOTHING: Transition(None, _K.KEEP),
    E.CLEARED_BACK: Transition("stop-alarm-back", _K.NEW_ALARM),
    E.RESET_ESTOP: Transition(None, _K.STOP_OVER_RESET),
    E.RESET_REFUSED: Transition("reset-refused", _K.NEW_ALARM),
    E.RESET_NOTHING: Transition("reset-refused", _K.KEEP),
    E.RESET_DONE: Transition(None, _K.CLEARED),
    E.RESET_DONE_PRESSED: Transition("estop-cleared", _K.KEEP),
    E.RESET_MISMATCHED: Transition(None, _K.KEEP),
    E.PRESS: Transition(None, _K.STOP_OVER),
    E.RELEASE: Transition(None, _K.KEEP),
}
_UNDER_STOP: Final[dict[LatchEvent, Transition]] = {  # 0E latched: another 0E or a press changes nothing
    **_ALARMS,
    E.ESTOP: Transition(None, _K.KEEP),
    E.SAME: Transition(None, _K.KEEP),
    E.RESET_ESTOP: Transition(None, _K.CLEAR_UNDER_STOP),
    E.PRESS: Transition(None, _K.KEEP),
    E.RELEASE: Transition(None, _K.RELEASE),
}
_UNSEEN: Final[dict[LatchEvent, Transition]] = {  # the release may have happened: no code is compared
    **_UNDER_STOP,
    E.NORMAL: Transition(None, _K.RELEASED),
    E.OTHER: Transition(None, _K.FORGET_STOP),
    E.NOTHING: Transition(None, _K.FORGET_STOP),
    E.CLEARED_BACK: Transition(None, _K.FORGET_STOP),  # new, perhaps: raised after the unseen release
    E.RESET_REFUSED: Transition("reset-refused", _K.FORGET_STOP),
    E.RESET_NOTHING: Transition("reset-refused", _K.FORGET_STOP),
    E.RESET_DONE: Transition(None, _K.CLEARED_RELEASED),
}

# (state, event) -> the rule it breaks and its effect: the whole latch, every pair
LATCH: Final[dict[tuple[LatchState, LatchEvent], Transition]] = {
    **{(S.FREE, e): t for e, t in {**_ALARMS, E.NORMAL: Transition(None, _K.FORGET_CLEARED),
                                   E.RESET_MISMATCHED: Transition(None, _K.FORGET_CLEARED)}.items()},
    **{(S.HELD, e): t for e, t in {
        **_ALARMS,
        E.NORMAL: Transition("latch-broken", _K.KEEP),
        E.OTHER: Transition("latch-code-changed", _K.NEW_ALARM),
        E.NOTHING: Transition("latch-code-changed", _K.KEEP),
    }.items()},
    **{(S.STOP, e): t for e, t in {
        **_UNDER_STOP,
        E.NORMAL: Transition("latch-broken", _K.KEEP),
        E.OTHER: Transition("latch-code-changed", _K.NEW_ALARM),
        E.NOTHING: Transition("latch-code-changed", _K.KEEP),
    }.items()},
    **{(S.STOP_UNSEEN, e): t for e, t in _UNSEEN.items()},
    **{(S.STOP_UNSEEN_OVER, e): t for e, t in {
        **_UNSEEN, E.NORMAL: Transition("stop-alarm-back", _K.RELEASED)}.items()},
}
assert len(LATCH) == len(LatchState) * len(LatchEvent), "every (state, event) pair has its cell"

# the alarm events: whether the code latches and whether the host then owes a reset (the other events
# are no alarm answer)
ALARM_EVENTS: Final[dict[LatchEvent, EventKind]] = {
    E.ESTOP: EventKind(True, True),
    E.SAME: EventKind(True, True),
    E.OTHER: EventKind(True, True),
    E.CLEARED_BACK: EventKind(True, True),
    E.NOTHING: EventKind(False, False),
    E.RESET_ESTOP: EventKind(True, False),
    E.RESET_REFUSED: EventKind(True, False),
    E.RESET_NOTHING: EventKind(False, False),
}


class StormState(Enum):
    """Where the host stands in a run of communication-error answers (``0%%01``)."""

    __hash__ = object.__hash__  # members are unique: hashed by identity, as they compare

    CALM = "below the storm limit"
    STORM = "the run reached the storm limit: the host must stop (vendor §6 caution)"
    RECOVERING = "at the limit, the last answer was 0%C00 to the host's reset"


# (storm state, is the line a well-formed reset) -> the host duty it breaks (None: none)
HOST_DUTY: Final[dict[tuple[StormState, bool], str | None]] = {
    (StormState.CALM, False): None,
    (StormState.CALM, True): None,
    (StormState.STORM, False): "comm-error-storm",
    (StormState.STORM, True): "storm-recovery",
    (StormState.RECOVERING, False): "storm-recovery",
    (StormState.RECOVERING, True): "storm-recovery",
}
assert len(HOST_DUTY) == 2 * len(StormState), "every (state, reset) pair has its cell"


def rules_named() -> frozenset[str]:
    """Every rule a cell of the tables names (checked against the rulebook and docs/protocol.md)."""
    return frozenset({t.rule for t in LATCH.values() if t.rule} | {r for r in HOST_DUTY.values() if r})
