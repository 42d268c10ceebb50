"""``xac1 decode --batch``: one conversation per file, a process per file, a row per file and a total."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import xac1

from sniffer.decode_batch import expand, total
from sniffer.io.pcap import PcapngWriter
from xac1_proto import frames as fr
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.cli import main

pytestmark = pytest.mark.slow  # xac1 decode processes

T0 = 1_790_000_000.0


def exchanges(n: int, broken_every: int = 0) -> list[Chunk]:
    """``n`` version reads answered 2 ms later; every ``broken_every``-th answer missing."""
    out = []
    cmd, ans = fr.ReadVersion().to_bytes(), fr.ReadVersionAnswer(version="100").to_bytes()
    for k in range(n):
        t = T0 + 3 * k
        out.append(Chunk(t, HOST, cmd))
        if not (broken_every and k % broken_every == broken_every - 1):
            out.append(Chunk(t + 0.002, DEVICE, ans))
    return out


def write_pcapng(path: Path, chunks: list[Chunk]) -> Path:
    with PcapngWriter(path) as w:
        for ch in chunks:
            w.write(ch)
    return path


@pytest.fixture
def archive(tmp_path: Path) -> Path:
    d = tmp_path / "archive"
    d.mkdir()
    write_pcapng(d / "a-clean.pcapng", exchanges(20))
    write_pcapng(d / "b-silent.pcapng", exchanges(30, broken_every=3))
    write_pcapng(d / "c-clean.pcapng", exchanges(5))
    (d / ".hidden.pcapng").write_bytes(b"")
    (d / "sub").mkdir()
    return d


def rows(out: str) -> list[dict]:
    return [json.loads(line) for line in out.splitlines()]


def test_expand_takes_directories_files_and_globs_in_order_without_repeats(archive):
    """``--batch`` arguments: files, directories and globs expand in order, each file once; what matches
    nothing is said."""
    files, wrong, skipped = expand([str(archive / "c-clean.pcapng"), str(archive), str(archive / "b-*"),
                                    str(archive / "nothing-*")])
    names = [Path(f).name for f in files]
    assert names == ["c-clean.pcapng", "a-clean.pcapng", "b-silent.pcapng"]
    assert wrong == [f"{archive / 'nothing-*'}: no file matches (a directory, a file or a glob pattern)"]
    assert skipped == []


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_batch_rows_are_each_files_own_summary_and_the_total_adds_them(archive, capsys, jobs):
    """A batch prints one row per file with that file's own summary, and a total that adds them; the status is
    the worst file's."""
    status = main(["decode", "--batch", str(archive), "--format", "jsonl", "--jobs", jobs])
    got = rows(capsys.readouterr().out)
    assert status == 1  # b-silent has no-answer violations
    assert [Path(r["file"]).name for r in got[:-1]] == ["a-clean.pcapng", "b-silent.pcapng", "c-clean.pcapng"]
    for row in got[:-1]:
        assert main(["decode", row["file"], "--format", "jsonl"]) == row["exit"]
        alone = rows(capsys.readouterr().out)[-1]  # the summary record of decoding the file alone
        assert {k: v for k, v in row.items() if k not in ("type", "file", "exit", "format")} == \
            {k: v for k, v in alone.items() if k != "type"}
        assert row["format"] == "pcap"
    t = got[-1]
    assert t["type"] == "total" and t["files"] == 3 and t["failed"] == 0
    assert t["frames"] == {"host": 55, "device": 45}
    assert t["violations"] == {"no-answer": 9} and t["unanswered"] == 1  # the last one: cut short
    assert t == total(got[:-1])


def test_one_and_two_jobs_print_the_same(archive, capsys):
    """The number of jobs changes nothing in what a batch prints."""
    outs = []
    for jobs in ("1", "2"):
        main(["decode", "--batch", str(archive / "*.pcapng"), "-f", "jsonl", "-j", jobs])
        outs.append(capsys.readouterr().out)
    assert outs[0] == outs[1]


def test_text_rows_and_a_failed_file(archive, capsys):
    """A file that decodes nothing is a failed row and makes the batch exit 2; the text rows name every
    file."""
    (archive / "d-notes.txt").write_text("not a capture\n")
    status = main(["decode", "--batch", str(archive), "-j", "2"])
    cap = capsys.readouterr()
    assert status == 2  # a file decoded nothing
    lines = cap.out.splitlines()
    assert lines[0].split()[:3] == ["file", "format", "host"]
    assert len(lines) == 1 + 4 + 1
    assert lines[-1].startswith("total (4 files, 1 failed)")
    assert "d-notes.txt" in cap.err


def test_per_record_options_are_refused_in_a_batch(archive, capsys):
    """Options about single records (``--only-violations``) are refused with ``--batch``, naming the
    option."""
    assert main(["decode", "--batch", str(archive), "--only-violations"]) == 2
    assert "--only-violations" in capsys.readouterr().err


def test_nothing_matches(tmp_path, capsys):
    """A batch whose patterns match no file says so and exits 2."""
    assert main(["decode", "--batch", str(tmp_path / "none-*.pcapng")]) == 2
    assert "no file matches" in capsys.readouterr().err


@pytest.mark.slow
def test_batch_as_a_user_runs_it(archive):
    """``xac1 decode --batch`` as a process: one row per file and the total, exit 1 for violations."""
    done = xac1("decode", "--batch", str(archive), "-f", "jsonl")
    assert done.returncode == 1, done.stderr
    assert [r["type"] for r in rows(done.stdout)] == ["file", "file", "file", "total"]
