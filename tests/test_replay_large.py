"""``xac1 replay --dry-run`` streams a capture of any size as ``xac1 decode`` does (issue 40 item 3: a
40 MB recording peaked at 449 MiB, decode at 29 MiB); figures for larger ones come from
``benchmarks/bench_replay_memory.py``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from bench_replay_memory import LIMIT_MB, write_recording
from conftest import ROOT, xac1
from peak_rss import run_measuring_peak_rss

DRY_RUN = [sys.executable, "-m", "xac1_proto", "replay", "--dry-run", "--format", "jsonl"]


@pytest.mark.slow  # starts processes, writes a 6 MB recording
def test_dry_run_memory_does_not_grow_with_the_recording(tmp_path: Path) -> None:
    """A recording of 40,000 exchanges peaks within ``LIMIT_MB`` (64 MiB) and within a few MiB of one
    of 2,000 (was 81 MiB, growing with the file: the whole script was held before a line was
    shown); every line is still shown, in order."""
    small, large = tmp_path / "small.jsonl", tmp_path / "large.jsonl"
    write_recording(small, 2_000)
    write_recording(large, 40_000)
    small_code, small_mb = run_measuring_peak_rss([*DRY_RUN, str(small)], cwd=ROOT)
    large_code, large_mb = run_measuring_peak_rss([*DRY_RUN, str(large)], cwd=ROOT)
    print(f"peak RSS {small_mb:.1f} MiB -> {large_mb:.1f} MiB")
    assert small_code == large_code == 0
    assert large_mb <= LIMIT_MB and large_mb < small_mb + 8, (small_mb, large_mb)
    done = xac1("replay", "--dry-run", "--format", "jsonl", str(small), timeout=120)
    objects = [json.loads(line) for line in done.stdout.splitlines()]
    assert done.returncode == 0, done.stderr
    assert [o["i"] for o in objects[:-1]] == list(range(0, 4_000, 2))
    assert objects[-1] == {"type": "summary", "dry_run": True, "lines": 2_000, "would_send": 2_000 - sum(
        1 for o in objects[:-1] if o["skipped"]), "skipped": sum(1 for o in objects[:-1] if o["skipped"])}
