"""The engine never blames a clean device for what the line cannot show (docs/protocol.md, silent items
11 and 18, "0RC before homing", the rules marked as our reading). Each test is named after the rule; each
failed before the fix it holds (issue 23)."""

from __future__ import annotations

from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from xac1_proto.conversation import KNOWN, LEARNT, UNKNOWN, Conversation, Verdict


def talk(*pairs: tuple[bytes, bytes | None],
         c: Conversation | None = None) -> tuple[list[Verdict], Conversation]:
    """Command and answer pairs, 0.1 s apart, the answer 2 ms after its command (None: silence)."""
    c = c or Conversation()
    out: list[Verdict] = []
    for k, (cmd, ans) in enumerate(pairs):
        t = 0.1 * k
        out += c.host_frame(cmd, t, t)
        if ans is not None:
            out += c.device_frame(ans, t + 0.002, t + 0.002)
    out += c.close()
    return out, c


def codes(verdicts: list[Verdict]) -> list[tuple[str, str]]:
    return [(code, side) for v in verdicts for code, side in zip(v.codes, v.sides, strict=True)]


# ---- item 1: mode 0 hands the OUT ports and the axis to the external I/O ----

def test_after_0cm0_the_out_ports_are_unknown_until_read_again():
    """After 0CM0 a PLC may switch the outputs: 0RS reading other ports than 0WS wrote is learnt, not a
    readback-mismatch (silent item 11); read once, the ports are judged again."""
    verdicts, c = talk((b"0WS12\r\n", b"0WS12\r\n"), (b"0CM0\r\n", b"0CM0\r\n"), (b"0RS\r\n", b"0RS02\r\n"),
                       (b"0RS\r\n", b"0RS12\r\n"))
    assert codes(verdicts) == [("readback-mismatch", "device")]
    assert verdicts[-1].header == "0RS"  # the second read is judged against the first
    assert (c.knowledge.outputs.value, c.knowledge.outputs.status) == (0, LEARNT)


def test_after_0cm0_the_position_is_unknown_until_read_again():
    """After 0CM0 a PLC may move or home the axis: 0RC answering another position than the last move,
    or a position where the axis was known not homed, is learnt (silent item 11)."""
    verdicts, c = talk((b"0MV3C3001000\r\n", b"0MV3C3001000\r\n"), (b"0CM0\r\n", b"0CM0\r\n"),
                       (b"0RC\r\n", b"0RC00002002000\r\n"))
    assert codes(verdicts) == []
    assert (c.knowledge.position.value, c.knowledge.position.status) == (0x2000, LEARNT)
    c = Conversation()
    c.power_on()
    verdicts, c = talk((b"0CM0\r\n", b"0CM0\r\n"), (b"0RC\r\n", b"0RC00002000000\r\n"), c=c)
    assert codes(verdicts) == [] and c.knowledge.homed.value is True


def test_0cm1_keeps_what_the_conversation_established():
    """Mode 1 disables the external I/O: after 0CM1 the OUT ports are still judged (silent item 11)."""
    verdicts, c = talk((b"0WS12\r\n", b"0WS12\r\n"), (b"0CM1\r\n", b"0CM1\r\n"), (b"0RS\r\n", b"0RS02\r\n"))
    assert codes(verdicts) == [("readback-mismatch", "device")]
    assert c.knowledge.outputs.status == KNOWN


ports = st.sampled_from([b"0", b"1", b"2", b"3"])


@settings(max_examples=budget(60), deadline=None)
@given(ports, ports, st.integers(0, 0xFFFFFE))
def test_no_read_after_0cm0_is_ever_blamed_on_the_device(written, read, pos):
    """Whatever a PLC did in mode 0, the first 0RS and 0RC after 0CM0 are never a readback-mismatch."""
    verdicts, c = talk((b"0WS" + written + b"2\r\n", b"0WS" + written + b"2\r\n"),
                       (b"0MV3C3001000\r\n", b"0MV3C3001000\r\n"), (b"0CM0\r\n", b"0CM0\r\n"),
                       (b"0RS\r\n", b"0RS" + read + b"2\r\n"),
                       (b"0RC\r\n", b"0RC000" + read + b"2" + b"%06X" % pos + b"\r\n"))
    assert codes(verdicts) == []
    assert c.knowledge.outputs.value == int(read) and c.knowledge.position.value == pos
    assert c.knowledge.position.status != UNKNOWN


# ---- item 2: Pos FFFFFF is the device stating it is not homed ----

def test_0rc_ffffff_is_learnt_never_judged_against_an_older_position():
    """0RC answering Pos FFFFFF after a move (a power cycle in a silence the line cannot show) is learnt
    as not homed, never a readback-mismatch ("Behaviour the vendor text states": 0RC before homing)."""
    verdicts, c = talk((b"0MV3C3001000\r\n", b"0MV3C3001000\r\n"), (b"0RC\r\n", b"0RC00002FFFFFF\r\n"))
    assert codes(verdicts) == []
    assert (c.knowledge.homed.value, c.knowledge.homed.status) == (False, LEARNT)
    assert c.knowledge.position.status == UNKNOWN


def test_homing_error_leaves_homing_to_be_learnt():
    """After a homing error (0%%0B) the axis may not be homed: 0RC's FFFFFF after the reset is learnt
    (docs/protocol.md "Alarms": homing after each alarm)."""
    verdicts, c = talk((b"0MV3C3001000\r\n", b"0MV3C3001000\r\n"), (b"0MP0\r\n", b"0%%0B\r\n"),
                       (b"0%C\r\n", b"0%C00\r\n"), (b"0RC\r\n", b"0RC00002FFFFFF\r\n"))
    assert codes(verdicts) == []
    assert c.knowledge.homed.value is False


def test_a_position_after_ffffff_is_learnt():
    """Learnt not homed (FFFFFF may be an unseen power cycle: mode 0, where the external I/O may home the
    axis, vendor §7 (10)): 0RC answering a position with no move between is learnt, not a
    readback-mismatch (issue 35, verdict 4; this test expected readback-mismatch before)."""
    verdicts, c = talk((b"0RC\r\n", b"0RC00002FFFFFF\r\n"), (b"0RC\r\n", b"0RC00002000000\r\n"))
    assert codes(verdicts) == []
    assert (c.knowledge.homed.value, c.knowledge.homed.status) == (True, LEARNT)


exchanges = st.lists(st.sampled_from([
    (b"0MV3C3001000\r\n", b"0MV3C3001000\r\n"), (b"0MP0\r\n", b"0MP00002000000\r\n"),
    (b"0MP0\r\n", b"0%%0B\r\n"), (b"0MV3C3001000\r\n", b"0%%09\r\n"), (b"0RV\r\n", b"0%%0E\r\n"),
    (b"0%C\r\n", b"0%C00\r\n"), (b"0RC\r\n", b"0RC00002001000\r\n"), (b"0WS12\r\n", b"0WS12\r\n"),
    (b"0CM0\r\n", b"0CM0\r\n"), (b"0RS\r\n", b"0RS12\r\n")]), max_size=12)


@settings(max_examples=budget(80), deadline=None)
@given(exchanges)
def test_0rc_ffffff_is_never_a_readback_mismatch(before):
    """Whatever came before, 0RC answered N, V, A 0 and Pos FFFFFF is never a readback-mismatch."""
    verdicts, c = talk(*before, (b"0%C\r\n", b"0%C00\r\n"), (b"0RC\r\n", b"0RC00002FFFFFF\r\n"))
    assert "readback-mismatch" not in verdicts[-1].codes
    assert c.knowledge.homed.value is False


# ---- item 5: rules that are our reading, not the vendor's ----

def test_alarm_ignored_is_a_notice():
    """The vendor says the device repeats the alarm answer; it sets the host no duty to reset first:
    polling 0RV during an emergency stop is the notice alarm-ignored, never an error."""
    verdicts, _ = talk((b"0RV\r\n", b"0%%0E\r\n"), (b"0RV\r\n", b"0%%0E\r\n"), (b"0RV\r\n", b"0%%0E\r\n"))
    assert codes(verdicts) == [("alarm-ignored", "host")] * 2
    assert all(not v.errors for v in verdicts)


STORM = [(b"0RP3\n", b"0%%01\r\n")] + [(b"0RV\r\n", b"0%%01\r\n")] * 4


def test_the_hosts_reset_and_first_command_after_it_are_storm_recovery_notices():
    """At the storm limit the host's own 0%C, and its first command after 0%C00, are recovering: the
    notice storm-recovery, not comm-error-storm; a second command is comm-error-storm again until an
    answer ends the run (docs/protocol.md "Behaviour the vendor text states")."""
    verdicts, _ = talk(*STORM, (b"0%C\r\n", b"0%C00\r\n"), (b"0RV\r\n", b"0%%01\r\n"),
                       (b"0RV\r\n", b"0%%01\r\n"))
    host = [v.codes for v in verdicts if v.kind == "host-frame"][5:]
    assert host == [("storm-recovery",), ("storm-recovery",), ("comm-error-storm", "alarm-ignored")]
    assert [v.errors for v in verdicts if v.kind == "host-frame"][5:7] == [(), ()]


def test_a_garbled_alarm_answer_neither_counts_nor_ends_the_storm_run():
    """A garbled alarm answer (a 0%% frame whose code cannot be read, or device junk) leaves the storm
    run as it was (docs/protocol.md "Behaviour the vendor text states")."""
    _, c = talk(*STORM[:3], (b"0RV\r\n", b"0%%\r\n"))
    assert c.knowledge.storm_run == 3
    c = Conversation()
    for k, (cmd, ans) in enumerate(STORM[:3]):
        c.host_frame(cmd, k * 0.1, k * 0.1)
        c.device_frame(ans, k * 0.1 + 0.002, k * 0.1 + 0.002)
    c.host_frame(b"0RV\r\n", 1.0, 1.0)
    c.device_junk(b"\x8f%%01\r\n", 1.002, 1.002)
    assert c.knowledge.storm_run == 3


@settings(max_examples=budget(60), deadline=None)
@given(st.lists(st.sampled_from([(b"0RV\r\n", b"0%%01\r\n"), (b"0RV\r\n", b"0%%0E\r\n"),
                                 (b"0%C\r\n", b"0%C00\r\n"), (b"0%C\r\n", b"0%%0E\r\n"),
                                 (b"0RV\r\n", b"0RV100\r\n"), (b"0XY\r\n", b"0%%01\r\n")]), max_size=14))
def test_a_reset_is_never_comm_error_storm(pairs):
    """Whatever came before, a well-formed 0%C, and the first command after its 0%C00, are never
    comm-error-storm; every other command at the limit is."""
    verdicts, c = talk(*pairs)
    hosts = [v for v in verdicts if v.kind == "host-frame"]
    for k, v in enumerate(hosts):
        after_reset = k > 0 and pairs[k - 1] == (b"0%C\r\n", b"0%C00\r\n")
        if v.header == "0%C" or after_reset:
            assert "comm-error-storm" not in v.codes
