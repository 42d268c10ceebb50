"""Benchmark: the capture readers alone, chunks per second, on the seeded field traffic of ``traffic.py``.

For each kind of traffic (``cell``, ``random``, ``anomalous``) and each file (RTAC-serial pcapng, socat
``-x`` log) of ``--exchanges`` exchanges, reads the file through ``sniffer.io.registry.Capture`` (what
``xac1 decode`` reads with) and counts its chunks; prints the best of ``--repeat`` runs in CPU seconds
of this process (a shared machine's load moves wall times more than CPU times). Run it with two checkouts'
environments, one after the other, to compare readers.

Run: ``python benchmarks/bench_readers.py [--exchanges 50000] [--repeat 7] [--kinds ...] [--formats ...]
[--keep DIR]``; the microseconds a chunk are the reciprocal of chunks/s.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import traffic  # noqa: E402

SUFFIXES = {"pcapng": ".pcapng", "socat": ".log"}
READ_AS = {"pcapng": "pcap", "socat": "socat"}


def chunks_per_second(path: Path, fmt: str, repeat: int) -> tuple[int, float]:
    """(chunks, best chunks/s in CPU time) of reading ``path`` ``repeat`` times."""
    from sniffer.io.registry import Capture

    best, n = float("inf"), 0
    for _ in range(repeat):
        t0 = time.process_time()
        with Capture([str(path)], READ_AS[fmt]) as capture:
            n = sum(1 for _ in capture)
        best = min(best, time.process_time() - t0)
    return n, n / best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exchanges", type=int, default=50_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--kinds", nargs="+", choices=traffic.KINDS, default=list(traffic.KINDS))
    ap.add_argument("--formats", nargs="+", choices=list(SUFFIXES), default=list(SUFFIXES))
    ap.add_argument("--keep", type=Path, help="write the generated files here and keep them (reused)")
    args = ap.parse_args(argv)
    workdir = args.keep or Path(tempfile.mkdtemp(prefix="xac1-readers-"))
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        print(f"{args.exchanges} exchanges a file, seed {args.seed}, best of {args.repeat} (CPU time)")
        print(f"{'traffic':10} {'file':7} {'chunks':>9} {'chunks/s':>11} {'us/chunk':>9}")
        for kind in args.kinds:
            for fmt in args.formats:
                suffix = SUFFIXES[fmt]
                path = workdir / f"{kind}-{args.exchanges}-seed{args.seed}{suffix}"
                if not path.exists():
                    traffic.WRITERS[fmt](traffic.conversation(args.exchanges, args.seed, kind), path)
                n, rate = chunks_per_second(path, fmt, args.repeat)
                print(f"{kind:10} {fmt:7} {n:9,} {rate:11,.0f} {1e6 / rate:9.3f}", flush=True)
    finally:
        if args.keep is None:
            shutil.rmtree(workdir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
