"""The client's judgement (its own conversation engine), its storm guard and how long it waits for a move;
the client on pyserial's loop:// port where a real port helps (what it sends comes back as the answer)."""

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


STROKE_END = spec.UNKNOWN_POSITION - 1  # the farthest position a move can reach (silent item 5)


def taught(start: int | None, point: tuple[int, int, int] | None, time_scale: float = 1.0) -> Client:
    """A client on loop:// that learnt from echoed answers: the axis at ``start`` (an 0MV to it; None: never
    moved) and point 1 as ``(v, a, pos)`` (an 0WP; None: never seen)."""
    c = Client("loop://", timeout=0.2, drain_quiet=0.01, time_scale=time_scale)
    if start is not None:
        c.transact(fr.MoveDirect(vel=1, a=1, pos=start).to_bytes())
    if point is not None:
        v, a, pos = point
        c.transact(fr.WritePoint(n=1, v=v, a=a, o=0, pos=pos).to_bytes())
    return c


def test_a_known_move_waits_its_motion_time_doubled_plus_the_timeout():
    """Once an answer told the position, a direct move waits the timeout plus its motion time (priced by
    ``motion.move_time``) doubled, the rulebook's answer window (docs/protocol.md silent item 17); a command
    that is no move waits the timeout."""
    with taught(0, None) as c:
        cmd = fr.MoveDirect(vel=30, a=2, pos=5000)
        assert c.position == 0
        assert c.move_timeout(cmd) == pytest.approx(
            0.2 + 2 * motion.move_time(5000, motion.DEFAULT_SPEEDS.direct_speed(30), 2))
        assert c.move_timeout(cmd) == c.conversation.answer_window(cmd)
        assert c.move_timeout(fr.ReadVersion()) == 0.2


@settings(max_examples=budget(50), deadline=None)
@given(command=frames("command"), known=st.booleans())
def test_a_command_that_is_no_move_waits_the_timeout(command, known):
    """Only 0MP and 0MV answer after a move: any other command waits the turnaround timeout, whether the
    position is known or not (regression: a 0RV waited for a homing over the whole stroke while the position
    was unknown, so a device that went silent held a conformance run for an hour)."""
    with taught(1000 if known else None, None) as c:
        if command.header in spec.MOVE_HEADERS:
            assert c.move_timeout(command) >= 0.2
        else:
            assert c.move_timeout(command) == 0.2


@settings(max_examples=budget(50), deadline=None)
@given(start=st.integers(0, STROKE_END), target=st.integers(0, STROKE_END), v=st.integers(1, 9),
       a=st.integers(1, 3))
def test_an_unknown_point_never_waits_less_than_a_known_one(start, target, v, a):
    """A point the client has not seen it prices at its worst: the wait for 0MP to it is never below the
    wait for the same point known, which covers the true move (docs/protocol.md silent item 17)."""
    move = fr.MovePoint(n=1)
    with taught(start, (v, a, target)) as known, taught(start, None) as unknown:
        true = known.move_timeout(move)
        assert true >= 0.2 + motion.move_time(abs(target - start), motion.DEFAULT_SPEEDS.point_speed(v), a)
        assert unknown.move_timeout(move) >= true


@pytest.mark.parametrize("time_scale", [0.0, 0.01, 0.5, 1.0])
def test_time_scale_scales_the_moves_share_of_the_window(time_scale):
    """``time_scale`` (a simulator run faster than real time) scales the move's share of the rulebook's
    window and never the turnaround timeout: 0 waits the timeout alone, 1 the whole window."""
    with taught(1000, (5, 2, 90000), time_scale) as c:
        for cmd in (fr.MovePoint(n=1), fr.MovePoint(n=0), fr.MovePoint(n=2),
                    fr.MoveDirect(vel=3, a=1, pos=7)):
            window = c.conversation.answer_window(cmd)
            assert window > 0.2
            assert c.move_timeout(cmd) == pytest.approx(0.2 + time_scale * (window - 0.2))


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
