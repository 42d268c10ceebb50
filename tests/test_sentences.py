"""Violations as codes (issue 35, item 3): the engine records a violation's rule, code, severity and the
few values its sentence needs; the sentence (``xac1_proto.sentences``) is made only where it is shown,
so ``--format summary`` (the analyzer counting verdicts, no record made) makes none. ``sentences.made``
is the public count of sentences made."""

from __future__ import annotations

from xac1_proto import sentences, spec
from xac1_proto.chunk import Chunk
from xac1_proto.conversation import Conversation

# a host that ignored one alarm and went on: every later exchange carries alarm-ignored and latch-broken
IGNORED = [(b"0RV\r\n", b"0%%08\r\n")] + [(b"0RV\r\n", b"0RV100\r\n"), (b"0RS\r\n", b"0RS12\r\n")] * 50


def _chunks() -> list[Chunk]:
    out = []
    for k, (cmd, ans) in enumerate(IGNORED):
        out += [Chunk(0.1 * k, spec.HOST_SIDE, cmd), Chunk(0.1 * k + 0.002, spec.DEVICE_SIDE, ans)]
    return out


def test_the_engine_makes_no_sentence_until_one_is_read():
    """Feeding a misbehaving conversation makes no sentence; reading a violation's ``message`` makes
    exactly its sentence, worded as the rule's (docs/protocol.md "Behaviour the vendor text states")."""
    c = Conversation()
    before = sentences.made()
    verdicts = []
    for k, (cmd, ans) in enumerate(IGNORED):
        t = 0.1 * k
        verdicts += c.host_frame(cmd, t, t) + c.device_frame(ans, t + 0.002, t + 0.002)
    verdicts += c.close()
    judged = [v for v in verdicts if v.violations]
    assert len(judged) == 2 * (len(IGNORED) - 1)
    assert {v.codes for v in judged} == {("alarm-ignored",), ("latch-broken",)}
    assert sentences.made() == before
    broken = next(v for v in judged if v.codes == ("latch-broken",)).violations[0]
    assert broken.message == (f"0RV got a normal answer while alarm 08 ({spec.alarm_meaning(8)}) should "
                              f"still be latched; docs/protocol.md \"Behaviour the vendor text states\" "
                              f"(latch-broken)")
    assert sentences.made() == before + 1


def test_a_summary_decode_makes_no_sentence():
    """The analyzer with no records asked for (``xac1 decode --format summary``) counts every violation
    of a misbehaving host's capture and makes no sentence."""
    from sniffer.analyzer import Analyzer

    before = sentences.made()
    a = Analyzer()
    while a.feed_many(iter(_chunks()), None):
        break
    a.close()
    assert a.tally.codes["alarm-ignored"] == a.tally.codes["latch-broken"] == len(IGNORED) - 1
    assert sentences.made() == before


def test_a_shown_record_makes_its_sentences():
    """Where a view shows violations (records), each detail is its sentence, made then."""
    from sniffer.analyzer import analyze

    before = sentences.made()
    records = analyze(_chunks())
    details = [d for r in records for d in getattr(r, "details", ())]
    assert len(details) == 2 * (len(IGNORED) - 1)
    assert sentences.made() == before + len(details)
    assert all(d.endswith(("(alarm-ignored)", "(latch-broken)")) for d in details)
