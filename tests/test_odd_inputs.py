"""Absurd inputs end as documented (issue 24, "Inputs"): a time no float holds is a located problem of
the capture, one file that breaks the decoder is one bad row of a batch, no reader holds a line without
end in memory whole (the format sniffing included), CR-only Saleae exports are read, and a batch names
what it leaves out."""

from __future__ import annotations

import io
import json
import os
import sys
from pathlib import Path

import pytest
from conftest import CAPTURES, ROOT, budget
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer import decode_batch
from sniffer.io import base, jsonl, saleae
from sniffer.io.base import MAX_LINE, Report, Source, time_problem
from xac1_proto.cli import main


def read(module, path: Path) -> tuple[list, Report]:
    report = Report()
    with Source(path, report) as src:
        return list(module.read(src)), report


# ---- 1. a time no float holds ----

@settings(max_examples=budget(60))
@given(st.one_of(st.integers(), st.integers(-10**500, 10**500).filter(lambda n: abs(n) > 10**308),
                 st.floats(allow_nan=True, allow_infinity=True)))
def test_any_number_is_a_time_or_says_why_not(t: int | float) -> None:
    """Any JSON number, however large (a 400-digit integer), is a capture time or a short reason why
    not: never an exception."""
    why = time_problem(t)
    assert why is None or (why.startswith("time ") and len(why) < 200)


@pytest.mark.parametrize("kind", ["recording", "decoded"])
def test_a_400_digit_time_is_a_located_problem(tmp_path: Path, kind: str) -> None:
    """A JSON-lines capture whose "t" is a 400-digit integer: that line's bytes are kept with the previous
    time and the problem names the file (and line), the rest is read (was: OverflowError)."""
    huge = int("9" * 400)
    f = tmp_path / "big.jsonl"
    if kind == "recording":
        f.write_text('{"type":"recording","version":1}\n'
                     '{"type":"chunk","t":1.0,"dir":"host","data":"3052560d0a"}\n'
                     f'{{"type":"chunk","t":{huge},"dir":"device","data":"3052563130300d0a"}}\n')
    else:
        f.write_text('{"type":"frame","i":0,"t":1.0,"dir":"host","raw":"3052560d0a"}\n'
                     f'{{"type":"frame","i":1,"t":{huge},"dir":"device","raw":"3052563130300d0a"}}\n')
    chunks, report = read(jsonl, f)
    assert [(c.t, c.data) for c in chunks] == [(1.0, b"0RV\r\n"), (1.0, b"0RV100\r\n")]
    assert len(report.problems) == 1 and "out of range" in report.problems[0]
    assert str(f) in report.problems[0] and len(report.problems[0]) < 300


def test_a_400_digit_time_decodes_with_the_status_of_a_capture_problem(tmp_path: Path, capsys) -> None:
    """``xac1 decode`` of that file: exit 1 with the problem on stderr, no traceback."""
    f = tmp_path / "big.jsonl"
    f.write_text('{"type":"frame","i":0,"t":1.0,"dir":"host","raw":"3052560d0a"}\n'
                 f'{{"type":"frame","i":1,"t":{"9" * 400},"dir":"device","raw":"3052563130300d0a"}}\n')
    assert main(["decode", str(f), "--format", "summary"]) == 1
    err = capsys.readouterr().err
    assert f"{f}:2: time" in err and "Traceback" not in err


def test_a_file_that_breaks_the_decoder_is_one_bad_row(tmp_path: Path, capsys) -> None:
    """Under ``--batch`` a file on which decoding raises (a bug) is one row with exit 2 and its error;
    the other files keep their rows and the total is printed (was: the whole batch aborted)."""
    good, bad = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    for f in (good, bad):
        f.write_text('{"type":"frame","i":0,"t":1.0,"dir":"host","raw":"3052560d0a"}\n')

    def decode(args, summaries) -> int:
        if args.files == [str(bad)]:
            raise OverflowError("int too large to convert to float")
        summaries.append({"type": "summary", "frames": {"host": 1, "device": 0}})
        return 0

    args = main_args(tmp_path)
    assert decode_batch.run(args, decode) == 2
    out, err = capsys.readouterr()
    rows = [json.loads(line) for line in out.splitlines()]
    assert [(r["type"], r.get("file"), r.get("exit")) for r in rows] == \
        [("file", str(good), 0), ("file", str(bad), 2), ("total", None, None)]
    assert rows[-1]["failed"] == 1 and rows[-1]["frames"] == {"host": 1, "device": 0}
    assert f"{bad}: internal error (OverflowError: " in err


def main_args(tmp_path: Path):
    import argparse

    return argparse.Namespace(files=[str(tmp_path / "*.jsonl")], batch=True, format="jsonl", jobs=1,
                              report=None, annotate=False, only_violations=False, header=False)


# ---- 2. a line with no end ----

@settings(max_examples=budget(40))
@given(st.binary(max_size=3 * MAX_LINE // 2), st.sampled_from([1, 7, MAX_LINE - 1, MAX_LINE, MAX_LINE + 3]))
def test_numbered_lines_come_in_bounded_pieces_that_add_up(data: bytes, long: int) -> None:
    """The reopened file's lines (sigrok's prescan and extra passes) come in pieces of at most
    ``MAX_LINE`` bytes, numbered as lines, and together hold every byte but the line ends."""
    content = data.replace(b"\r", b"") + b"x" * long  # LF ends only: each piece's end is known
    pieces = list(base.numbered_lines(io.BufferedReader(io.BytesIO(content))))  # type: ignore[arg-type]
    assert all(len(text) <= MAX_LINE for _n, text in pieces)
    assert "".join(text for _n, text in pieces) == content.replace(b"\n", b"").decode("latin-1")
    numbers = [n for n, _t in pieces]
    assert numbers == sorted(numbers) and numbers[-1] == content.count(b"\n") + 1


@pytest.mark.slow
@pytest.mark.parametrize(("capture", "line_end"), [
    ("sigrok-uart.txt", b"\n"), ("spy.log", b"\n"), ("interceptty.log", b"\n"), ("jpnevulator.txt", b"\n"),
    ("saleae-logic2.csv", b"\n"), ("saleae-logic2.csv", b"\r"), ("recording.jsonl", b"\n"),
    ("socat-x.log", b"\n")])
def test_an_80_mib_line_without_end_stays_under_64_mib(tmp_path: Path, capture: str, line_end: bytes) -> None:
    """A capture of each text format (Saleae also with CR-only line ends) followed by an 80 MiB line
    with no line end: the decoder, the format sniffing and prescans included, peaks under the 64 MiB
    bound (was 220-229 MiB for a 100 MB sigrok line) and reports the line as a problem (exit 1)."""
    from peak_rss import run_measuring_peak_rss

    f = tmp_path / f"long-{capture}"
    with f.open("wb") as out:
        out.write((CAPTURES / capture).read_bytes().replace(b"\n", line_end))
        for _ in range(80):
            out.write(b"3" * (1 << 20))
    code, peak = run_measuring_peak_rss([sys.executable, "-m", "xac1_proto", "decode", str(f),
                                         "--format", "summary"], cwd=ROOT)
    assert code == 1  # the long line is a problem of the capture, the rest is decoded
    assert peak < 64, f"peak {peak:.0f} MiB"


# ---- 3. CR-only line ends ----

ROWS = ["Time [s],Value,Parity Error,Framing Error", "0.10,0x30,,", "0.11,0x52,,", "0.12,0x56,,",
        "0.13,0x0D,,", "0.14,0x0A,,", "0.15,'1',,Error"]
TABLE = ['name,type,start_time,duration,data', '"uart A","data",0.1,0.001,0x30',
         '"uart A","data",0.101,0.001,0x0A', '"uart B","data",0.2,0.001,0x31']


@settings(max_examples=budget(30))
@given(st.sampled_from([ROWS, TABLE]), st.sampled_from(["\n", "\r\n", "\r"]), st.booleans(),
       st.integers(0, 3))
def test_saleae_reads_lf_crlf_and_cr_alone_the_same(tmp_path_factory, rows: list[str], end: str,
                                                    last_end: bool, blank: int) -> None:
    """A Saleae export reads to the same chunks and problems whatever its line ends: LF, CR LF, or CR
    alone (as some exports on other systems write); blank lines and a missing last line end alike."""
    d = tmp_path_factory.mktemp("saleae")
    expected = d / "lf.csv"
    expected.write_text("\n".join(rows) + "\n")
    f = d / "odd.csv"
    f.write_bytes((end.join(rows) + end * blank + (end if last_end else "")).encode())
    chunks, report = read(saleae, f)
    want, _ = read(saleae, expected)
    assert chunks == want and chunks
    assert report.problems == [] or (not last_end and not blank and "no line end" in report.problems[0])


def test_a_cr_only_saleae_capture_decodes_like_the_original(tmp_path: Path, capsys) -> None:
    """``xac1 decode`` of the gallery's Logic 2 table with every LF turned into a CR prints what the
    original gives (was: exit 2, "no line data found")."""
    original = CAPTURES / "saleae-logic2.csv"
    f = tmp_path / "cr.csv"
    f.write_bytes(original.read_bytes().replace(b"\n", b"\r"))
    want = main(["decode", str(original), "--format", "jsonl"]), capsys.readouterr().out
    assert (main(["decode", str(f), "--format", "jsonl"]), capsys.readouterr().out) == want


# ---- 4. what a batch leaves out ----

def test_batch_names_the_fifos_and_devices_it_leaves_out(tmp_path: Path, capsys) -> None:
    """``--batch DIR`` decodes DIR's regular files and names each FIFO or device it leaves out, with
    why; a FIFO named on its own is refused (exit 2) the same way (was: skipped without a word)."""
    (tmp_path / "a.jsonl").write_text('{"type":"frame","i":0,"t":1.0,"dir":"host","raw":"3052560d0a"}\n')
    fifo = tmp_path / "b.fifo"
    os.mkfifo(fifo)
    (tmp_path / "c-null").symlink_to("/dev/null")
    (tmp_path / "sub").mkdir()
    files, wrong, skipped = decode_batch.expand([str(tmp_path)])
    assert files == [str(tmp_path / "a.jsonl")] and wrong == []
    assert [m.split(": skipped: ")[0] for m in skipped] == [str(fifo), str(tmp_path / "c-null")]
    assert "a FIFO (named pipe)" in skipped[0] and "a character device" in skipped[1]
    assert main(["decode", "--batch", str(tmp_path), "--format", "jsonl"]) == 0
    err = capsys.readouterr().err
    assert f"xac1 decode: {fifo}: skipped: a FIFO (named pipe), not a regular file" in err
    assert main(["decode", "--batch", str(fifo)]) == 2
    assert f"{fifo}: skipped: a FIFO" in capsys.readouterr().err
