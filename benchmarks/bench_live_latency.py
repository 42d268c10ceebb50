"""Benchmark: the live sniffer's analyzer cost per chunk (``Analyzer.feed`` with ticks between chunks).

``xac1 sniff`` feeds each chunk as a tap gives it and ticks once a poll (``sniffer.live``: every 50 ms at
most), so a poll may end between a command and its answer. This replays a seeded conversation
(``traffic.py``: each kind) through ``Analyzer.feed`` with a ``tick`` after each chunk with
probability ``--tick`` (1: every chunk), and reports microseconds per chunk, records made, best of
``--rounds``. Issues 14 and 22: the live sniffer's per-chunk latency must not get worse; compare with the
figures of an earlier commit run on the same machine (benchmarks/README.md).

Run: ``python benchmarks/bench_live_latency.py [--exchanges 30000] [--tick 1 0.5 0.1]``.
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import traffic  # noqa: E402

from sniffer.analyzer import Analyzer  # noqa: E402
from xac1_proto.chunk import Chunk  # noqa: E402


def per_chunk_us(chunks: list[Chunk], ticks: list[bool]) -> float:
    analyzer = Analyzer()
    t0 = time.perf_counter()
    for chunk, tick in zip(chunks, ticks, strict=True):
        analyzer.feed(chunk)
        if tick:
            assert chunk.t is not None
            analyzer.tick(chunk.t + 0.0005)
    analyzer.close()
    return (time.perf_counter() - t0) / len(chunks) * 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exchanges", type=int, default=30_000)
    ap.add_argument("--tick", type=float, nargs="+", default=[1.0, 0.5, 0.1],
                    help="probability of a tick after a chunk (default: 1 0.5 0.1)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    print(f"{args.exchanges} exchanges, best of {args.rounds}; microseconds per chunk")
    print(f"{'traffic':10} {'tick':>5} {'us/chunk':>10}")
    for kind in traffic.KINDS:
        chunks = list(traffic.conversation(args.exchanges, args.seed, kind))
        for p in args.tick:
            rng = random.Random(args.seed)
            ticks = [rng.random() < p for _ in chunks]
            best = min(per_chunk_us(chunks, ticks) for _ in range(args.rounds))
            print(f"{kind:10} {p:5.2f} {best:10.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
