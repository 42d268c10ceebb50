"""The benchmarks' field traffic (benchmarks/traffic.py): clean kinds that today's analyzer finds
faultless, values that vary as a real device's do, anomalies every tenth exchange, a host that ignored an
alarm and one flooding communication errors (every later exchange judged), files that read back."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
import traffic
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.analyzer import Analyzer
from sniffer.io.registry import Capture
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk

CLEAN = ("cell", "random")
HERE = Path(__file__).resolve().parent


def decode(chunks: list[Chunk]) -> list[tuple[str, tuple[str, ...]]]:
    """(record type, violation codes) of every record the analyzer makes of ``chunks``."""
    analyzer = Analyzer()
    records = [r for c in chunks for r in analyzer.feed(c)] + analyzer.close()
    return [(r.type, tuple(getattr(r, "violations", ()))) for r in records]


def answers(chunks: list[Chunk], header: bytes) -> list[bytes]:
    return [c.data for c in chunks if c.dir == DEVICE and c.data.startswith(header)]


@pytest.mark.parametrize("kind", CLEAN)
def test_clean_kinds_decode_with_no_violation(kind: traffic.Kind) -> None:
    """Clean traffic is what a clean device and a correct host exchange: every one of a few hundred
    exchanges decodes as two frames with no violation, nothing is junk or unanswered."""
    chunks = list(traffic.conversation(400, seed=3, kind=kind))
    assert [c.dir for c in chunks] == [HOST, DEVICE] * 400
    records = decode(chunks)
    assert [t for t, _ in records] == ["frame"] * 800
    assert [codes for _, codes in records if codes] == []


@settings(max_examples=budget(12), deadline=None)
@given(seed=st.integers(0, 2**32), kind=st.sampled_from(CLEAN))
def test_clean_kinds_are_clean_for_any_seed(seed: int, kind: traffic.Kind) -> None:
    """Whatever the seed, the clean kinds' opening and first cycles (homing, teaching, moves, polls,
    toggles, read-backs) break no rule."""
    records = decode(list(traffic.conversation(60, seed=seed, kind=kind)))
    assert [codes for _, codes in records if codes] == []


def test_cell_values_vary_as_a_device_s_do() -> None:
    """The cell's traffic is not a few exchanges repeated: the position read (0RC) changes with every
    move, the outputs (0RS) take every value, and the host toggles them (0WS) after each poll."""
    chunks = list(traffic.conversation(2000, seed=1, kind="cell"))
    positions = answers(chunks, b"0RC")
    assert len(positions) > 250
    assert len(set(positions)) > 60  # 8 taught points with the outputs of the moment, and free moves
    assert len({a[-8:-2] for a in positions}) > 40  # the Pos field itself
    assert len(set(answers(chunks, b"0RS"))) == 4
    assert len(set(answers(chunks, b"0WS"))) == 4
    hosts = Counter(c.data[:3] for c in chunks if c.dir == HOST)
    assert hosts[b"0WP"] == traffic.TAUGHT
    assert {b"0MP", b"0RC", b"0RS", b"0WS", b"0RP", b"0MV"} <= set(hosts)


def test_random_field_values_are_fresh() -> None:
    """Random-field traffic carries new values: almost every point written or read, and every position
    moved to or read, is one not seen before in the file; the outputs take every value."""
    chunks = list(traffic.conversation(2000, seed=1, kind="random"))
    for header in (b"0WP", b"0RP", b"0MP", b"0MV", b"0RC"):
        seen = answers(chunks, header)
        assert len(seen) > 100, header
        assert len(set(seen)) > 0.9 * len(seen), header
    assert len(set(answers(chunks, b"0WS"))) == 4
    assert len(set(answers(chunks, b"0RS"))) == 4


def test_move_answers_come_after_the_move() -> None:
    """A move's answer comes after the move's time (homing and the trapezoid of xac1_proto.motion), every
    other answer after a turnaround of 1-3 ms plus its own wire time at 9600 baud."""
    chunks = list(traffic.conversation(300, seed=5, kind="cell"))
    for command, answer in zip(chunks[::2], chunks[1::2], strict=True):
        assert command.t is not None and answer.t is not None
        gap = answer.t - command.t - len(answer.data) * spec.BYTE_TIME_S
        if command.data[:3] in (b"0MP", b"0MV"):
            assert gap > 0.01, command.data
        else:
            assert 0.001 <= gap <= 0.003 + 1e-9, command.data


def test_anomalous_breaks_a_rule_every_tenth_exchange() -> None:
    """Anomalous traffic is the cell's, the same seed, with every tenth exchange spoiled (its command,
    or its answer, or the answer missing), cycling through the six faults; each spoiled exchange is
    judged, the others' bytes are the cell's."""
    n = 120
    cell = list(traffic.conversation(n, seed=2, kind="cell"))
    bad = list(traffic.conversation(n, seed=2, kind="anomalous"))
    commands = [c.data for c in cell if c.dir == HOST]
    spoiled = [c.data for c in bad if c.dir == HOST]
    assert len(spoiled) == n
    differs = [i for i in range(n) if spoiled[i] != commands[i]]
    assert set(differs) <= set(range(9, n, 10))
    assert len(differs) == 4  # letter O and lower case, twice each in twelve faults
    records = decode(bad)
    faulty = Counter(code for _, codes in records for code in codes)
    for code in ("letter-o", "no-answer", "bad-terminator", "lowercase-hex", "bad-length"):
        assert faulty[code] >= 1, code
    assert sum(1 for c in bad if c.dir == DEVICE) == n - 2  # two silences in twelve faults


def frame_codes(chunks: list[Chunk]) -> list[tuple[str, bytes, tuple[str, ...]]]:
    """(direction, bytes, violation codes) of every frame record the analyzer makes of ``chunks``."""
    analyzer = Analyzer()
    records = [r for c in chunks for r in analyzer.feed(c)] + analyzer.close()
    assert [r.type for r in records] == ["frame"] * len(chunks)
    return [(r.dir, r.raw, tuple(r.violations)) for r in records]


def test_misbehaving_host_ignores_the_alarm_on_every_later_exchange() -> None:
    """Misbehaving traffic is the cell's until its device answers an alarm; the host goes on without a
    reset and the device, forgetting the alarm, answers normally: every later host line is
    ``alarm-ignored`` and every later answer ``latch-broken``, and nothing before the alarm is judged."""
    n = 600
    frames = frame_codes(list(traffic.conversation(n, seed=6, kind="misbehaving")))
    alarm = next(k for k, (d, raw, _) in enumerate(frames) if d == DEVICE and raw.startswith(b"0%%"))
    assert alarm == 2 * traffic.MISBEHAVE_AT + 1
    assert frames[alarm][1] == b"0%%%%%02X\r\n" % traffic.MISBEHAVING_ALARM
    assert [codes for _, _, codes in frames[:alarm + 1] if codes] == []
    later = frames[alarm + 1:]
    assert len(later) == 2 * (n - traffic.MISBEHAVE_AT - 1)
    assert all(codes == ("alarm-ignored",) for d, _, codes in later if d == HOST)
    assert all(codes == ("latch-broken",) for d, _, codes in later if d == DEVICE)


def test_misbehaving_values_vary_as_the_cell_s_do() -> None:
    """After the ignored alarm the device answers as a working cell's does: the position read (0RC) and
    the outputs (0RS) keep changing, no alarm answer is repeated."""
    chunks = list(traffic.conversation(1500, seed=1, kind="misbehaving"))
    later = chunks[2 * traffic.MISBEHAVE_AT + 2:]
    assert len(set(answers(later, b"0RC"))) > 40
    assert len(set(answers(later, b"0RS"))) == 4
    assert answers(later, b"0%%") == []


def test_storm_host_floods_communication_errors() -> None:
    """Storm traffic is the cell's until the host starts sending every command with a bad length; each
    is answered ``0%%01``, and once ``spec.STORM_LIMIT`` are in a row every later command is also
    ``comm-error-storm``. The commands go on carrying the cell's varying values."""
    n = 400
    chunks = list(traffic.conversation(n, seed=6, kind="storm"))
    frames = frame_codes(chunks)
    start = 2 * traffic.MISBEHAVE_AT
    assert [codes for _, _, codes in frames[:start] if codes] == []
    hosts = [codes for d, _, codes in frames[start:] if d == HOST]
    devices = [raw for d, raw, _ in frames[start:] if d == DEVICE]
    assert all("bad-length" in codes for codes in hosts)
    assert devices == [b"0%%01\r\n"] * len(devices) and len(devices) == n - traffic.MISBEHAVE_AT
    assert all("comm-error-storm" in codes for codes in hosts[spec.STORM_LIMIT:])
    assert not any("comm-error-storm" in codes for codes in hosts[:spec.STORM_LIMIT])
    assert len({c.data for c in chunks[start:] if c.dir == HOST}) > 15


@pytest.mark.parametrize("kind", ["misbehaving", "storm"])
def test_misbehaving_kinds_are_seeded(kind: traffic.Kind) -> None:
    """The misbehaving kinds are seeded like the others: the same seed gives the same chunks, another
    seed other ones."""
    def run(seed: int) -> list[Chunk]:
        return list(traffic.conversation(80, seed=seed, kind=kind))

    assert run(11) == run(11)
    assert run(11) != run(12)


@pytest.mark.parametrize("fmt", ["socat", "pcapng"])
@pytest.mark.parametrize("kind", traffic.KINDS)
def test_written_files_read_back_as_the_chunks(tmp_path: Path, fmt: str, kind: traffic.Kind) -> None:
    """The socat and pcapng writers' files read back (through the readers decode uses) as the very
    chunks generated, times to the microsecond, with no problem reported."""
    chunks = list(traffic.conversation(150, seed=4, kind=kind))
    path = tmp_path / ("t.pcapng" if fmt == "pcapng" else "t.log")
    traffic.WRITERS[fmt](iter(chunks), path)
    with Capture([str(path)], "pcap" if fmt == "pcapng" else fmt) as capture:
        back = list(capture)
        problems = list(capture.report.problems)
    assert [(c.dir, c.data) for c in back] == [(c.dir, c.data) for c in chunks]
    assert [c.t for c in back] == pytest.approx([c.t for c in chunks], abs=2e-6)
    assert problems == []


def test_same_seed_same_traffic_other_seed_other() -> None:
    """Traffic is seeded: the same seed gives the same chunks, another seed other ones."""
    def run(seed: int) -> list[Chunk]:
        return list(traffic.conversation(100, seed=seed, kind="random"))

    assert run(7) == run(7)
    assert run(7) != run(8)


def test_unknown_kind_is_refused() -> None:
    """A kind that is not one of the known ones is a clear error naming them."""
    with pytest.raises(ValueError, match="cell, random, anomalous"):
        next(traffic.conversation(1, kind="clean"))  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["socat", "pcapng"])
def test_cli_writes_the_asked_kind_and_format(tmp_path: Path, fmt: str) -> None:
    """``python benchmarks/traffic.py OUT --exchanges N --kind K --format F`` writes that file: the same
    bytes as the writer gives for ``conversation(N, 1, K)``."""
    out, expected = tmp_path / "cli.out", tmp_path / "lib.out"
    subprocess.run([sys.executable, str(HERE.parent / "benchmarks" / "traffic.py"), str(out),
                    "--exchanges", "50", "--kind", "random", "--format", fmt], check=True,
                   capture_output=True)
    traffic.WRITERS[fmt](traffic.conversation(50, 1, "random"), expected)
    assert out.read_bytes() == expected.read_bytes()
