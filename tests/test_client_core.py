"""The client's sans-IO parts: answer judgement, the storm guard and move budgets (no port involved)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

from xac1_proto import AlarmError, ProtocolError, motion, spec
from xac1_proto import frames as fr
from xac1_proto.exchange import Exchange, StormGuard, answer_or_raise, judge_answer
from xac1_proto.movewait import FULL_STROKE, MoveBudget

VENDOR = [  # docs/protocol.md "Frames": vendor examples (command, answer)
    (b"0RP3\r\n", b"0RP39302012345\r\n"),
    (b"0WP19302012345\r\n", b"0WP19302012345\r\n"),
    (b"0RV\r\n", b"0RV100\r\n"),
]


def codes(violations):
    return [v.code for v in violations]


@pytest.mark.parametrize(("sent", "raw"), VENDOR)
def test_vendor_examples_are_clean(sent, raw):
    """The vendor's example exchanges break no rule (docs/protocol.md "Frames")."""
    frame, violations = judge_answer(sent, raw)
    assert violations == [] and frame is not None and frame.to_bytes() == raw


def test_answer_to_another_command_is_answer_mismatch():
    """An answer of another command is `answer-mismatch` (docs/protocol.md "Violation codes")."""
    _, violations = judge_answer(b"0RV\r\n", b"0RS02\r\n")
    assert codes(violations) == ["answer-mismatch"]


def test_answer_for_another_n_is_answer_mismatch():
    """0RP/0WC/0MP answers carry the N asked for; another N is `answer-mismatch` at N's offset."""
    _, violations = judge_answer(b"0RP3\r\n", b"0RP49302012345\r\n")
    assert codes(violations) == ["answer-mismatch"] and violations[0].offset == 3


def test_echo_that_differs_is_echo_mismatch():
    """0WP answers the command byte for byte; a difference is `echo-mismatch` at the first bad byte."""
    _, violations = judge_answer(b"0WP19302012345\r\n", b"0WP19302012346\r\n")
    assert codes(violations) == ["echo-mismatch"] and violations[0].offset == 13


def test_garbage_and_grammar_violations_are_kept():
    """Junk received with the answer is `garbage`; the grammar's own violations come along."""
    _, violations = judge_answer(b"0RV\r\n", b"0RV10\r\n", junk=b"\x00")
    assert codes(violations) == ["garbage", "bad-length"]


@settings(max_examples=150, deadline=None)
@given(command=frames("command"), answer=frames("answer"))
def test_mismatch_iff_other_header(command, answer):
    """Any well-formed answer: the alarm answer fits every command; otherwise the header must be the
    command's (docs/protocol.md "Frames": "alarm answer (to any command)")."""
    _, violations = judge_answer(command.to_bytes(), answer.to_bytes())
    other = answer.header not in (command.header, spec.ALARM_HEADER)
    assert ("answer-mismatch" in codes(violations)) == (other or (
        command.header == answer.header and hasattr(answer, "n") and hasattr(command, "n")
        and not answer.frame_spec().echo and answer.n != command.n))


def test_answer_or_raise():
    """Errors raise ProtocolError with the code and raw bytes; alarms raise AlarmError with the
    meaning from the spec's table; a clean answer is returned."""
    frame, violations = judge_answer(b"0RV\r\n", b"0%%08\r\n")
    with pytest.raises(AlarmError) as alarm:
        answer_or_raise(Exchange(b"0RV\r\n", b"0%%08\r\n", frame, violations, 0.001))
    assert alarm.value.code == 8 and alarm.value.meaning == spec.alarm_meaning(8)
    frame, violations = judge_answer(b"0RV\r\n", b"0RV1000\r\n")
    with pytest.raises(ProtocolError) as bad:
        answer_or_raise(Exchange(b"0RV\r\n", b"0RV1000\r\n", frame, violations, 0.001))
    assert bad.value.code == "bad-length" and bad.value.raw == b"0RV1000\r\n"
    frame, violations = judge_answer(b"0RV\r\n", b"0RV100\r\n")
    assert answer_or_raise(Exchange(b"0RV\r\n", b"0RV100\r\n", frame, violations, 0.001)) == frame


ALARM_01 = fr.AlarmAnswer(code=spec.ALARM_COMM)
answers = st.sampled_from([ALARM_01, fr.AlarmAnswer(code=8), fr.AlarmResetAnswer(), fr.ReadVersionAnswer(
    version="100"), None])


@settings(max_examples=100, deadline=None)
@given(st.lists(answers, max_size=20), st.integers(1, 6))
def test_storm_guard_counts_comm_errors_since_last_normal_answer(seq, limit):
    """docs/protocol.md host duty: count 0%%01 answers since the last normal answer (latched repeats
    count; the reset answer and other alarms neither count nor end the run); halt at the limit."""
    guard = StormGuard(limit)
    for answer in seq:
        guard.observe(answer)
    since = seq
    normal = [i for i, a in enumerate(seq) if isinstance(a, fr.ReadVersionAnswer)]
    if normal:
        since = seq[normal[-1] + 1:]
    expected = sum(1 for a in since if a == ALARM_01)
    assert guard.in_row == expected and guard.halted == (expected >= limit)
    guard.rearm()
    assert guard.in_row == 0 and not guard.halted


def test_storm_guard_disabled_and_unclean_answers():
    """storm_limit None never halts; an answer that broke the protocol does not end a run."""
    guard = StormGuard(None)
    for _ in range(50):
        guard.observe(ALARM_01)
    assert not guard.halted
    guard = StormGuard(2)
    guard.observe(ALARM_01)
    guard.observe(fr.ReadVersionAnswer(version="100"), clean=False)
    guard.observe(ALARM_01)
    assert guard.halted


def test_budget_known_move_is_motion_time():
    """After an answer told the position, a direct move costs motion.move_time from there."""
    budget = MoveBudget()
    budget.observe(fr.MovePoint(n=0), fr.MovePointAnswer(n=0, v=0, a=0, o=0, pos=0), clean=True)
    cmd = fr.MoveDirect(vel=30, a=2, pos=5000)
    assert budget.estimate(cmd) == motion.move_time(5000, motion.DEFAULT_SPEEDS.direct_speed(30), 2)
    assert budget.estimate(fr.ReadVersion()) is None


@settings(max_examples=100, deadline=None)
@given(start=st.integers(0, FULL_STROKE), target=st.integers(0, FULL_STROKE), v=st.integers(1, 9),
       a=st.integers(1, 3))
def test_budget_unknown_is_never_less_than_known(start, target, v, a):
    """Unknown position or point data is priced at the worst case: never below the true move."""
    known = MoveBudget()
    known.observe(fr.MoveDirect(vel=1, a=1, pos=start),
                  fr.MoveDirectAnswer(vel=1, a=1, pos=start), clean=True)
    known.observe(fr.ReadPoint(n=1), fr.ReadPointAnswer(n=1, v=v, a=a, o=0, pos=target), clean=True)
    true = known.estimate(fr.MovePoint(n=1))
    unknown_pos = MoveBudget()
    unknown_pos.observe(fr.ReadPoint(n=1), fr.ReadPointAnswer(n=1, v=v, a=a, o=0, pos=target), clean=True)
    assert unknown_pos.estimate(fr.MovePoint(n=1)) >= true
    assert MoveBudget().estimate(fr.MovePoint(n=1)) >= true


def test_budget_forgets_after_alarm_and_estop():
    """A move without a clean answer leaves the position unknown; emergency stop unhomes the axis."""
    budget = MoveBudget()
    budget.observe(fr.MovePoint(n=0), fr.MovePointAnswer(n=0, v=0, a=0, o=0, pos=0), clean=True)
    budget.observe(fr.MoveDirect(vel=1, a=1, pos=10), fr.AlarmAnswer(code=9), clean=True)
    assert budget.position is None and budget.homed
    budget.observe(fr.ReadVersion(), fr.AlarmAnswer(code=spec.ALARM_ESTOP), clean=True)
    assert budget.homed is False
