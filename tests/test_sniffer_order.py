"""When one poll finds several exchanges waiting on both taps (a sniffer that fell behind), they are
merged back answer-first, so nothing is invented; host lines read alone stay together, so true
back-to-back commands are still seen (docs/protocol.md "Violation codes": overlapping-command)."""

from __future__ import annotations

from collections import Counter

from sniffer.analyzer import Analyzer
from sniffer.order import CausalOrder
from xac1_proto.chunk import DEVICE, HOST, Chunk


def _ordered():
    a = Analyzer()
    records: list = []
    order = CausalOrder(lambda c: records.extend(a.feed(c)), lambda: a.waiting, lambda: a.expecting_answer)
    return a, records, order


def test_one_poll_with_both_taps_is_merged_answer_first():
    """Three exchanges read in one poll (each tap's bytes in one chunk, a command still held from the
    poll before) come out command, answer, command, answer...: no violation, each answer paired."""
    a, records, order = _ordered()
    order.push_poll([Chunk(1.0, HOST, b"0RV\r\n")], now=0.0)
    order.push_poll([Chunk(1.2, HOST, b"0RS\r\n0WS12\r\n"),
                     Chunk(1.2, DEVICE, b"0RV100\r\n0RS02\r\n0WS12\r\n")], now=0.2)
    records += a.close()
    assert Counter(c for r in records for c in r.violations) == Counter()
    answers = [r for r in records if r.dir == DEVICE]
    assert [(r.header, r.reply_to) for r in answers] == [("0RV", 0), ("0RS", 2), ("0WS", 4)]


def test_host_lines_read_alone_stay_together():
    """Two commands read together before any answer: the second overlaps the first."""
    a, records, order = _ordered()
    order.push_poll([Chunk(1.0, HOST, b"0RV\r\n0RS\r\n")], now=0.0)
    order.push_poll([Chunk(1.1, DEVICE, b"0RV100\r\n0RS02\r\n")], now=0.1)
    records += a.close()
    assert Counter(c for r in records for c in r.violations) == Counter({"overlapping-command": 1})
