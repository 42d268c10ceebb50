"""The client's judgement (its own conversation engine), its storm guard and move budgets; the client on
pyserial's loop:// port where a real port helps (what it sends comes back as the answer)."""

from __future__ import annotations

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import frames

from xac1_proto import AlarmError, Client, CommunicationHalted, ProtocolError, motion, spec
from xac1_proto import frames as fr
from xac1_proto.conversation import Conversation
from xac1_proto.exchange import Exchange, answer_or_raise
from xac1_proto.movewait import FULL_STROKE, MoveBudget

VENDOR = [  # docs/protocol.md "Frames": vendor examples (command, answer)
    (b"0RP3\r\n", b"0RP39302012345\r\n"),
    (b"0WP19302012345\r\n", b"0WP19302012345\r\n"),
    (b"0RV\r\n", b"0RV100\r\n"),
]


def codes(violations):
    return [v.code for v in violations]


def judge(sent: bytes, raw: bytes) -> tuple[fr.Frame | None, list]:
    """What the client's rulebook says of the answer ``raw`` to ``sent`` (a fresh conversation)."""
    c = Conversation()
    c.host_frame(sent, 0.0, 0.0)
    verdict = c.device_frame(raw, 0.001, 0.001)[-1]
    return verdict.frame, list(verdict.violations)


@pytest.fixture
def loop_client():
    """The client on pyserial's loop:// port: what it sends comes back as the answer (an echo device)."""
    c = Client("loop://", timeout=0.2, drain_quiet=0.01)
    yield c
    c.close()


@pytest.mark.parametrize(("sent", "raw"), VENDOR)
def test_vendor_examples_are_clean(sent, raw):
    """The vendor's example exchanges break no rule (docs/protocol.md "Frames")."""
    frame, violations = judge(sent, raw)
    assert violations == [] and frame is not None and frame.to_bytes() == raw


def test_answer_to_another_command_is_answer_mismatch():
    """An answer whose header is another command's is answer-mismatch (docs/protocol.md "Violation codes")."""
    _, violations = judge(b"0RP3\r\n", b"0RV100\r\n")
    assert codes(violations) == ["answer-mismatch"]


def test_answer_for_another_n_is_answer_mismatch():
    """0RP, 0WC, 0MP answers carry the N asked for (docs/protocol.md "Frames")."""
    _, violations = judge(b"0RP3\r\n", b"0RP49302012345\r\n")
    assert codes(violations) == ["answer-mismatch"]


def test_echo_that_differs_is_echo_mismatch():
    """An echo answer repeats the command's fields (docs/protocol.md "Behaviour the vendor text states")."""
    _, violations = judge(b"0WS12\r\n", b"0WS22\r\n")
    assert codes(violations) == ["echo-mismatch"]


def test_echo_is_judged_by_fields_not_bytes(loop_client):
    """Regression (issue 12): a lower-case echo is the lowercase-hex notice, never echo-mismatch; the
    client on a real port says so and returns the answer."""
    ex = loop_client.transact(b"0WP1930201abcd\r\n")
    assert codes(ex.violations) == ["lowercase-hex"] and ex.sides == ["device"] and not ex.errors
    assert answer_or_raise(ex) == fr.WritePointAnswer(n=1, v=9, a=3, o=0, pos=0x1ABCD)


def test_garbage_and_grammar_violations_are_kept(loop_client):
    """Bytes before the answer that form no frame are garbage; the answer's own violations follow."""
    loop_client.port.write(b"\xfe")  # noise already on the line is stale: reported apart
    ex = loop_client.transact(b"\xff0RV\r\n")  # comes back as noise, then a 0RV answer 3 bytes short
    assert ex.stale == b"\xfe" and ex.junk == b"\xff"
    assert codes(ex.violations) == ["garbage", "bad-length"]
    ex = loop_client.transact(b"0RS1\r\n")  # malformed, and answered normally: error-accepted
    assert codes(ex.violations) == ["bad-length", "missing-2", "error-accepted"]


@settings(max_examples=budget(50), deadline=None)
@given(command=frames("command"), answer=frames("answer"))
def test_mismatch_iff_other_header(command, answer):
    """Any well-formed answer: the alarm answer fits every command; otherwise the header must be the
    command's (docs/protocol.md "Frames": "alarm answer (to any command)")."""
    _, violations = judge(command.to_bytes(), answer.to_bytes())
    other = answer.header not in (command.header, spec.ALARM_HEADER)
    assert ("answer-mismatch" in codes(violations)) == (other or (
        command.header == answer.header and hasattr(answer, "n") and hasattr(command, "n")
        and not answer.frame_spec().echo and answer.n != command.n))


def test_answer_or_raise():
    """Errors raise ProtocolError with the code and raw bytes; alarms raise AlarmError with the
    meaning from the spec's table; a clean answer is returned."""
    frame, violations = judge(b"0RV\r\n", b"0%%08\r\n")
    with pytest.raises(AlarmError) as alarm:
        answer_or_raise(Exchange(b"0RV\r\n", b"0%%08\r\n", frame, violations, 0.001))
    assert alarm.value.code == 8 and alarm.value.meaning == spec.alarm_meaning(8)
    frame, violations = judge(b"0RV\r\n", b"0RV1000\r\n")
    with pytest.raises(ProtocolError) as bad:
        answer_or_raise(Exchange(b"0RV\r\n", b"0RV1000\r\n", frame, violations, 0.001))
    assert bad.value.code == "bad-length" and bad.value.raw == b"0RV1000\r\n"
    frame, violations = judge(b"0RV\r\n", b"0RV100\r\n")
    assert answer_or_raise(Exchange(b"0RV\r\n", b"0RV100\r\n", frame, violations, 0.001)) == frame


def test_storm_run_ends_on_any_other_answer_even_with_a_framing_fault(loop_client):
    """Regression (issue 12), the one storm rule (docs/protocol.md host duty): 0%%01 x4, then a normal
    answer with a framing fault (0RV100 + space) ends the run; 0%%01 x2 more do not halt the client. On
    loop:// the line sent is the answer received."""
    c = loop_client
    for _ in range(4):
        assert c.transact(b"0%%01\r\n").alarm == fr.AlarmAnswer(code=spec.ALARM_COMM)
    assert c.comm_errors_in_row == 4
    ex = c.transact(b"0RV100 \r\n")
    assert "bad-length" in codes(ex.violations) and c.comm_errors_in_row == 0
    for _ in range(2):
        c.transact(b"0%%01\r\n")
    assert c.comm_errors_in_row == 2 and not c.halted
    c.transact(b"0%C00\r\n")  # the reset answer neither counts nor ends the run
    assert c.comm_errors_in_row == 2
    c.transact(b"0%%08\r\n")  # an alarm of another code ends it
    assert c.comm_errors_in_row == 0


def test_storm_halts_and_is_disabled_with_none():
    """The fifth 0%%01 in a row halts the client (CommunicationHalted, nothing sent) until rearm();
    storm_limit=None never halts."""
    with Client("loop://", timeout=0.2, drain_quiet=0.01) as c:
        for _ in range(5):
            c.transact(b"0%%01\r\n")
        assert c.halted
        with pytest.raises(CommunicationHalted):
            c.transact(b"0RV\r\n")
        c.rearm()
        assert not c.halted and c.transact(b"0RV100\r\n").frame == fr.ReadVersionAnswer(version="100")
    with Client("loop://", timeout=0.2, drain_quiet=0.01, storm_limit=None) as c:
        for _ in range(7):
            c.transact(b"0%%01\r\n")
        assert c.comm_errors_in_row == 7 and not c.halted


def test_default_timeout_is_the_projects_one():
    """One answer-timeout default for client, sniffer and suite (docs/protocol.md silent item 17)."""
    with Client("loop://") as c:
        assert c.timeout == spec.NO_ANSWER_TIMEOUT_S


def test_budget_known_move_is_motion_time():
    """After an answer told the position, a direct move costs motion.move_time from there."""
    budget = MoveBudget()
    budget.observe(fr.MovePoint(n=0), fr.MovePointAnswer(n=0, v=0, a=0, o=0, pos=0), clean=True)
    cmd = fr.MoveDirect(vel=30, a=2, pos=5000)
    assert budget.estimate(cmd) == motion.move_time(5000, motion.DEFAULT_SPEEDS.direct_speed(30), 2)
    assert budget.estimate(fr.ReadVersion()) is None


@settings(max_examples=budget(100), deadline=None)
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


def test_malformed_move_gets_the_plain_timeout():
    """Regression: a malformed 0MV (vel 00) is no move, so a silent device costs the plain timeout, not
    a move priced at speed 0 (found by the cross-check against a device silent to malformed commands)."""
    import time

    from xac1_proto import ResponseTimeout

    with Client("xac1sim://?time_scale=0&deviation=silent-on-malformed", timeout=0.2, drain_quiet=0.01) as c:
        start = time.monotonic()
        with pytest.raises(ResponseTimeout):
            c.transact(b"0MV0030004AB\r\n")
        assert time.monotonic() - start < 2.0
