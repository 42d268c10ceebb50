"""The engine never blames a clean device for what the line cannot show (docs/protocol.md, silent items
11 and 18, "0RC before homing", the rules marked as our reading). Each test is named after the rule; each
failed before the fix it holds (issue 23)."""

from __future__ import annotations

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


@settings(max_examples=60, deadline=None)
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
