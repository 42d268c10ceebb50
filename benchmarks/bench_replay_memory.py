"""Benchmark: ``xac1 replay --dry-run --format jsonl`` memory on a large recording, beside decode's.

Run on demand: ``python benchmarks/bench_replay_memory.py [--exchanges 300000]``. Writes a JSON lines
recording (``xac1_proto.recording.RecordingWriter``) of ``--exchanges`` command/answer pairs (reads,
writes, moves and OUT writes, one chunk a frame, 20 ms apart) and a small one of 5,000, then runs
``xac1 replay --dry-run -f jsonl`` and ``xac1 decode -f summary`` on each in a child process and
reports each child's peak resident memory (``peak_rss.py``: the child's alone) and time. The script is
streamed as decode streams (``sniffer.replay_script.ScriptStream``), so the peak stays under 64 MiB
whatever the size; exits 1 when it passes that.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from peak_rss import run_measuring_peak_rss  # this script's directory is on sys.path

from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.recording import RecordingWriter

ROOT = Path(__file__).resolve().parent.parent
LIMIT_MB = 64  # issue 40 item 3: at most 64 MiB for any size, as decode
EXCHANGES = ((b"0RV\r\n", b"0RV100\r\n"), (b"0RP3\r\n", b"0RP3521200123A\r\n"),
             (b"0WP3521200123A\r\n", b"0WP3521200123A\r\n"), (b"0RC\r\n", b"0RC0000200123A\r\n"),
             (b"0WS02\r\n", b"0WS02\r\n"), (b"0RS\r\n", b"0RS02\r\n"))


def write_recording(path: Path, exchanges: int) -> int:
    """A recording of ``exchanges`` command/answer pairs; its size in bytes."""
    t = 1_700_000_000.0
    with RecordingWriter(path, source="bench_replay_memory") as rec:
        for k in range(exchanges):
            command, answer = EXCHANGES[k % len(EXCHANGES)]
            rec.write(Chunk(t, HOST, command))
            rec.write(Chunk(t + 0.008, DEVICE, answer))
            t += 0.02
    return path.stat().st_size


def peak(args: list[str]) -> tuple[float, float]:
    """(peak RSS in MiB, seconds) of ``xac1 ARGS`` in a child process, its output discarded."""
    t0 = time.perf_counter()
    code, peak_mib = run_measuring_peak_rss([sys.executable, "-m", "xac1_proto", *args], cwd=ROOT)
    if code != 0:
        raise SystemExit(f"xac1 {' '.join(args)} exited {code}")
    return peak_mib, time.perf_counter() - t0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--exchanges", type=int, default=300_000,
                   help="command/answer pairs in the large recording (default 300000: about 40 MB)")
    args = p.parse_args()
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for n in (5_000, args.exchanges):
            path = Path(tmp) / f"r{n}.jsonl"
            size = write_recording(path, n)
            replay_mb, replay_s = peak(["replay", "--dry-run", "-f", "jsonl", str(path)])
            decode_mb, decode_s = peak(["decode", "-f", "summary", str(path)])
            worst = max(worst, replay_mb)
            print(f"{n} exchanges ({size / 1e6:.1f} MB): replay --dry-run -f jsonl peak {replay_mb:.1f} MiB "
                  f"({replay_s:.1f} s); decode -f summary peak {decode_mb:.1f} MiB ({decode_s:.1f} s)")
    print(f"target: <= {LIMIT_MB} MiB")
    return 0 if worst <= LIMIT_MB else 1


if __name__ == "__main__":
    sys.exit(main())
