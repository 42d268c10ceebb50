"""Fuzzing ``xac1 decode`` (issue 13, "Tests it must have"): every reader, fed truncations and mutations
of every gallery capture (bit flips, inserted CR/LF/NUL, huge and non-finite numbers, impossible dates,
block lengths of 0, 12, past the end and 2^32-4), through every output format, gives records and
problem messages: never another exception, never a hang. The worst inputs found are kept as files in
``tests/corpus/decode/`` and replayed here through every reader.

Decoding runs in this process (``decode_cli.run`` with its output captured) so that hypothesis can try
hundreds of inputs in seconds; each decode has a time limit. The number of examples and whether they are
derandomized come from the hypothesis profile in use (CI: derandomized)."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
import shutil
import signal
import struct
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import budget
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sniffer import decode_cli
from sniffer.io.registry import NAMES

ROOT = Path(__file__).resolve().parent.parent
CAPTURES = ROOT / "captures"
CORPUS = Path(__file__).resolve().parent / "corpus" / "decode"
PARTNERS = {"saleae-host.csv": "saleae-device.csv", "saleae-device.csv": "saleae-host.csv",
            "saleae-ascii-host.csv": "saleae-ascii-device.csv",
            "saleae-ascii-device.csv": "saleae-ascii-host.csv",
            "raw-host.bin": "raw-device.bin", "raw-device.bin": "raw-host.bin"}
GALLERY = sorted(p.name for p in CAPTURES.iterdir() if p.is_file() and p.suffix != ".py"
                 and p.name != "README.md")
FILES = {name: (CAPTURES / name).read_bytes() for name in GALLERY}
READERS = ("auto", *NAMES)
OUTPUTS = ("text", "jsonl", "summary")
TIME_LIMIT_S = 20  # one decode of a small file taking longer is a hang
INSERTS = (b"\r", b"\n", b"\0", b"\r\n", b"\n\n", b"\r\r\r")
NUMBERS = (b"1e14", b"NaN", b"nan", b"inf", b"-inf", b"Infinity", b"1e308", b"-1", b"27", b"32", b"99",
           b"0", b"00", b"99999999999999999999999999", b"9" * 5000, b"0.000000000000000001")
LENGTHS = (0, 12, 13, 2**32 - 4, 2**31)


class Hang(Exception):
    pass


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    def expire(signum: int, frame: object) -> None:
        raise Hang(f"decode took more than {seconds} s")

    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def decode(files: list[Path], reader: str, output: str) -> tuple[int, str, str]:
    """``xac1 decode FILES --input-format READER --format OUTPUT`` in this process."""
    parser = argparse.ArgumentParser()
    decode_cli.add_arguments(parser)
    args = parser.parse_args([*map(str, files), "--input-format", reader, "--format", output,
                              "--no-color"])
    out, err = io.StringIO(), io.StringIO()
    with time_limit(TIME_LIMIT_S), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = decode_cli.run(args)
    return code, out.getvalue(), err.getvalue()


def check(code: int, out: str, err: str, output: str) -> None:
    """What every decode must give: a documented exit status, a message for each non-zero one, the
    summary record last in JSON lines output, the problem count matching the messages."""
    assert code in (0, 1, 2), code
    if code == 2:
        assert err.strip(), "exit 2 without a message"
        return
    if output == "jsonl":
        lines = out.splitlines()
        assert lines, "no output"
        last = json.loads(lines[-1])
        assert last["type"] == "summary"
        for line in lines[:-1]:
            assert json.loads(line)["type"] in ("frame", "junk", "timeout")
        if code == 0:
            assert "problems" not in last and not last["violations"]
        if "problems" in last:
            assert last["problems"] >= len(last["problem_messages"]) >= 1
    else:
        assert "summary" in out


def block_length_offsets(data: bytes) -> list[int]:
    """Where the lengths of pcapng blocks (both copies) or pcap records are, in a gallery file."""
    if data[:4] == b"\x0a\x0d\x0d\x0a":
        out, i = [], 0
        while i + 8 <= len(data):
            total = struct.unpack_from("<I", data, i + 4)[0]
            if total < 12:  # damaged already: the blocks after it cannot be found
                break
            out += [i + 4, i + total - 4]
            i += total
        return out
    if data[:4] == b"\xd4\xc3\xb2\xa1":
        out, i = [], 24
        while i + 16 <= len(data):
            out.append(i + 8)
            i += 16 + struct.unpack_from("<I", data, i + 8)[0]
        return out
    return []


@st.composite
def damaged(draw: st.DrawFn) -> tuple[str, bytes]:
    """A gallery file with one to four kinds of damage."""
    name = draw(st.sampled_from(GALLERY))
    data = bytearray(FILES[name])
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(("truncate", "flip", "insert", "number", "length")))
        if op == "truncate":
            del data[draw(st.integers(0, len(data))):]
        elif op == "flip" and data:
            data[draw(st.integers(0, len(data) - 1))] ^= 1 << draw(st.integers(0, 7))
        elif op == "insert":
            at = draw(st.integers(0, len(data)))
            data[at:at] = draw(st.sampled_from(INSERTS))
        elif op == "length" and block_length_offsets(bytes(data)):
            at = draw(st.sampled_from(block_length_offsets(bytes(data))))
            value = draw(st.sampled_from((*LENGTHS, len(data) + 64)))
            data[at:at + 4] = struct.pack("<I", value & 0xFFFFFFFF)
        else:
            numbers = list(re.finditer(rb"\d+(?:\.\d+)?", bytes(data)))
            if numbers:
                m = draw(st.sampled_from(numbers))
                data[m.start():m.end()] = draw(st.sampled_from(NUMBERS))
    return name, bytes(data)


def place(tmp: Path, name: str, data: bytes) -> Path:
    """The damaged file under its gallery name, its partner (other direction) next to it unchanged."""
    path = tmp / name
    path.write_bytes(data)
    if name in PARTNERS and not (tmp / PARTNERS[name]).exists():
        shutil.copy(CAPTURES / PARTNERS[name], tmp / PARTNERS[name])
    return path


@settings(deadline=None, max_examples=budget(300),
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(damage=damaged(), reader=st.sampled_from(READERS), output=st.sampled_from(OUTPUTS))
def test_damaged_gallery_captures_never_raise_or_hang(tmp_path: Path, damage: tuple[str, bytes],
                                                      reader: str, output: str) -> None:
    """A damaged gallery capture, through any reader and output, gives a clear status and message, never a
    traceback or a hang."""
    name, data = damage
    folder = tmp_path / f"case{abs(hash((name, data, reader, output))) % 10**9}"
    folder.mkdir(exist_ok=True)
    code, out, err = decode([place(folder, name, data)], reader, output)
    check(code, out, err, output)


@pytest.mark.parametrize("reader", READERS)
def test_every_reader_reads_every_gallery_file(tmp_path: Path, reader: str) -> None:
    """Each reader given each gallery capture (mostly of another format): a decode or a message."""
    for name in GALLERY:
        for output in ("jsonl", "text") if reader == "auto" else ("jsonl",):
            code, out, err = decode([CAPTURES / name], reader, output)
            check(code, out, err, output)
            if reader == "auto":
                assert code == 1, (name, err)  # the gallery session has violations


CORPUS_FILES = sorted(p for p in CORPUS.iterdir() if p.suffix != ".md") if CORPUS.is_dir() else []


def test_the_corpus_is_there() -> None:
    """The corpus of worst inputs found has not gone missing (the fuzz test would then pass on nothing)."""
    assert len(CORPUS_FILES) >= 10, "tests/corpus/decode/ holds the worst inputs found"


@pytest.mark.parametrize("path", CORPUS_FILES, ids=[p.name for p in CORPUS_FILES])
def test_corpus_of_worst_inputs_replays(path: Path) -> None:
    """Each kept input: detected, its problems located (exit 1, or 2 when nothing was left to decode);
    then every reader and every output on it: no exception, no hang."""
    code, out, err = decode([path], "auto", "jsonl")
    check(code, out, err, "jsonl")
    assert code in (1, 2) and f"{path}:" in err, err
    for reader in READERS:
        for output in OUTPUTS:
            check(*decode([path], reader, output), output)
