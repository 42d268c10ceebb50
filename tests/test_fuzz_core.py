"""The fuzz core (xac1_proto.fuzz): never a move, cases from the grammar, findings, the shrinker."""

from __future__ import annotations

import itertools
import random
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st

from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST
from xac1_proto.codec import diagnose
from xac1_proto.framer import MAX_FRAME
from xac1_proto.frames import StoreCurrent, WriteOutputsAnswer, WritePoint, WritePointAnswer
from xac1_proto.fuzz import guard
from xac1_proto.fuzz.cases import ALL_POINTS, GENERATORS, Case, Context, cases, finish, next_case
from xac1_proto.fuzz.judge import ANSWER, SILENCE, Expectation, Transcript, probe_finding, state_finding
from xac1_proto.fuzz.shrink import shrink

ROOT = Path(__file__).resolve().parent.parent
POINTS = sorted(ALL_POINTS)

# Every way a lenient controller could read the motion headers: case, letter O, eighth bit, NUL inside.
_VARIANTS = st.sampled_from(["0MP", "0MV", "0mp", "0mv", "OMP", "oMv", "0Mp"]).flatmap(
    lambda h: st.tuples(st.just(h.encode()), st.lists(st.booleans(), min_size=3, max_size=3),
                        st.lists(st.booleans(), min_size=3, max_size=3)))


def _disguise(variant: tuple[bytes, list[bool], list[bool]]) -> bytes:
    header, high, nul = variant
    return b"".join(bytes([b | (0x80 if h else 0)]) + (b"\x00" if n else b"")
                    for b, h, n in zip(header, high, nul, strict=True))


@settings(max_examples=budget(2000))
@given(st.sampled_from(sorted(GENERATORS)), st.integers(0, 2 ** 32),
       st.frozensets(st.sampled_from(POINTS)))
def test_no_generator_emits_a_motion_header(name, seed, writable):
    """No case of any generator, whatever the seed and the writable points, carries 0MP or 0MV read
    leniently (lower case, letter O, eighth bit dropped, NUL skipped) anywhere in its bytes."""
    case = finish(name, GENERATORS[name](random.Random(seed), Context(writable)), Context(writable))
    assert guard.motion_at(case.data) is None, (name, case)
    guard.check(case.data)
    text, _ = guard.lenient(case.data)
    assert "0MP" not in text and "0MV" not in text
    assert not case.motion


@settings(max_examples=budget(500))
@given(st.integers(0, 2 ** 32))
def test_the_case_stream_sends_no_move_without_a_safe_range(seed):
    """Without --allow-motion (no safe range) the stream of cases never holds a move case, and every case
    ends on a LF so the probe after it starts on a fresh line."""
    for case in itertools.islice(cases(seed, Context()), 20):
        assert not case.motion and guard.motion_at(case.data) is None
        assert case.data.endswith(b"\n")


@settings(max_examples=budget(1000))
@given(st.binary(max_size=40), _VARIANTS, st.binary(max_size=40))
def test_the_guard_refuses_a_motion_header_anywhere(before, variant, after):
    """A motion header anywhere in the bytes, in any lenient disguise, is refused before sending; defuse
    makes any bytes pass, changing no more bytes than there were headers."""
    data = before + _disguise(variant) + after
    with pytest.raises(guard.MotionLine):
        guard.check(data)
    safe = guard.defuse(data)
    guard.check(safe)
    assert len(safe) == len(data)
    assert sum(a != b for a, b in zip(safe, data, strict=True)) <= data.count(b"M") + data.count(b"m") + \
        data.count(bytes([ord("M") | 0x80])) + data.count(bytes([ord("m") | 0x80]))


@settings(max_examples=budget(1000))
@given(st.sampled_from(sorted(GENERATORS)), st.integers(0, 2 ** 32),
       st.frozensets(st.sampled_from(POINTS), max_size=4))
def test_no_case_writes_a_point_it_may_not(name, seed, writable):
    """On a real unit the cases write only the points the run can write back: no line, read as a lenient
    controller would (upper-cased too), is a 0WP or 0WC to another point."""
    ctx = Context(writable)
    case = finish(name, GENERATORS[name](random.Random(seed), ctx), ctx)
    for line in case.data.split(b"\n"):
        for candidate in (line + b"\n", line.upper() + b"\n"):
            frame, _ = diagnose(candidate, spec.COMMAND)
            if isinstance(frame, (WritePoint, StoreCurrent)):
                assert frame.n in writable, (name, case)


def test_cases_are_reproducible_and_cover_the_issue_list():
    """The same seed gives the same cases; over a few hundred cases every generator appears, with lines
    well past the frame sizes, NUL and bytes above 0x7F, lower case, floods and partial frames."""
    a = list(itertools.islice(cases(7, Context()), 600))
    assert a == list(itertools.islice(cases(7, Context()), 600))
    assert a != list(itertools.islice(cases(8, Context()), 600))
    assert {c.kind for c in a} == set(GENERATORS)
    longest = max(len(line) for c in a for line in c.data.split(b"\n"))
    assert longest > 2 * MAX_FRAME
    data = b"".join(c.data for c in a)
    assert b"\x00" in data and any(b > 0x7F for b in data)
    assert any(len(c.lines) > 1 and not c.lines[0].endswith(b"\n") for c in a if c.kind == "partial")
    assert any(c.data.count(b"\n") >= 5 for c in a if c.kind == "flood")


def test_moves_only_inside_the_safe_range():
    """With a safe range, some cases are well-formed direct moves, every one inside the range."""
    rng = random.Random(3)
    moves = [c for c in (next_case(rng, Context(ALL_POINTS, (0x100, 0x200))) for _ in range(300)) if c.motion]
    assert moves
    for c in moves:
        frame, violations = diagnose(c.lines[0], spec.COMMAND)
        assert not violations and 0x100 <= frame.pos <= 0x200


def test_the_shrinker_finds_the_shortest_line():
    """A fault set off by any line longer than 40 bytes is shrunk from a flood of lines to one line of 41
    bytes (CR LF included)."""
    lines = (b"0RV\r\n", b"x" * 300 + b"\r\n", b"0RS\r\n", b"y" * 100 + b"\n")
    calls = []

    def still(candidate):
        calls.append(candidate)
        return any(len(x) + 1 > 40 for x in b"".join(candidate).split(b"\n"))  # its LF counted

    result = shrink(lines, still, Context())
    assert len(result.lines) == 1 and len(result.lines[0]) == 41, result
    assert result.tries == len(calls) and not result.exhausted


@settings(max_examples=budget(200))
@given(st.lists(st.binary(min_size=1, max_size=12), min_size=1, max_size=5))
def test_the_shrinker_never_invents_a_move(parts):
    """Cutting bytes out of a case never joins them into a motion header: every candidate the shrinker
    tries passes the guard, even from lines built around 0MxP and 0MxV."""
    lines = tuple(guard.defuse(p + b"0MXP" + p + b"0mxv\n") for p in parts)
    tried = []

    def still(candidate):
        tried.append(candidate)
        guard.check(b"".join(candidate))
        return True

    result = shrink(lines, still, Context(), budget=60)
    guard.check(b"".join(result.lines))
    assert all(guard.motion_at(b"".join(c)) is None for c in tried)


def test_probe_findings():
    """Silence is no answer in the window (late answers say how late); a different answer to 0RV is an
    ``answer`` finding; the same answer is none."""
    rv = b"0RV100\r\n"
    assert probe_finding(rv, rv, b"0RV\r\n", late_s=None, window_s=0.2) is None
    kind, detail = probe_finding(rv, b"", b"0RV\r\n", late_s=None, window_s=0.2)
    assert kind == SILENCE and "no answer within 0.20 s" in detail
    kind, detail = probe_finding(rv, b"", b"0RV\r\n", late_s=0.7, window_s=0.2)
    assert kind == SILENCE and "only 0.70 s after it was sent (late)" in detail
    assert probe_finding(None, b"0%%0E\r\n", b"0%C\r\n", late_s=None, window_s=0.2) is None
    kind, detail = probe_finding(rv, b"0%%01\r\n", b"0RV\r\n", late_s=None, window_s=0.2)
    assert kind == ANSWER and "'0%%01'" in detail


def test_expectation_accounts_for_what_the_cases_wrote():
    """A point or OUT port the unit acknowledged writing is expected changed; a change nobody asked for
    is a state finding naming the point, what it reads and what was expected."""
    start = {n: (0, 0, 0, 0) for n in POINTS}
    expect = Expectation(dict(start), 0)
    expect.observe([WritePointAnswer(n=2, v=1, a=1, o=0, pos=0x10), WriteOutputsAnswer(o=3)])
    now = dict(start)
    now[2] = (1, 1, 0, 0x10)
    assert state_finding(expect, now, 3) is None
    now[1] = (0, 0, 0, 0x100)
    detail = state_finding(expect, now, 3)
    assert detail is not None and "point 1 reads V=0 A=0 O=0 Pos=000100" in detail
    assert "point 2 written (0WP)" in detail


def test_transcript_names_the_device_violation():
    """The run's transcript is judged by the engine: a line left unanswered past the window is
    ``no-answer``, laid on the device; the host's own garbage is not the device's fault."""
    t = Transcript(no_answer_timeout=0.1)
    mark = t.mark()
    t.add(HOST, b"\x00garbage\r\n", 1.0)
    t.add(DEVICE, b"0%%01\r\n", 1.01)
    assert t.device_codes(mark) == ()
    mark = t.mark()
    t.add(HOST, b"0RV\r\n", 2.0)
    t.tick(3.0)
    assert t.device_codes(mark) == ("no-answer",)
    assert [c.dir for c in t.since(mark)] == [HOST]


def test_the_core_is_sans_io():
    """The fuzz core loads no serial port, socket, thread or subprocess module, and its source imports no
    clock (time, datetime): time comes in as an argument."""
    modules = ["guard", "cases", "judge", "shrink", "results"]
    code = ("import sys\n" + "".join(f"import xac1_proto.fuzz.{m}\n" for m in modules) +
            "print(' '.join(sorted(sys.modules)))")
    loaded = set(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                cwd=ROOT).stdout.split())
    assert not loaded & {"serial", "socket", "threading", "subprocess", "asyncio", "select", "selectors"}
    for m in modules:
        source = (ROOT / "xac1_proto" / "fuzz" / f"{m}.py").read_text()
        assert "import time" not in source and "datetime" not in source, m


def test_case_data_is_its_writes():
    """A case's bytes are its writes joined, in order."""
    assert Case("x", (b"0R", b"V\r\n")).data == b"0RV\r\n"


@pytest.mark.parametrize(("name", "seed"), [("length", 23), ("nul-high", 882), ("random", 7562)])
def test_raw_generator_output_with_a_header_is_defused(name, seed):
    """Spoiling bytes at random does make motion headers (0\\xEDP is 0MP with the eighth bit dropped; a
    random 0\\xB0m\\xD6 is 0MV): these seeds do, and the finished case no longer carries one."""
    raw = b"".join(GENERATORS[name](random.Random(seed), Context()))
    assert guard.motion_at(raw) is not None
    case = finish(name, GENERATORS[name](random.Random(seed), Context()), Context())
    assert guard.motion_at(case.data) is None
