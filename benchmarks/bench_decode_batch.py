"""Benchmark: ``xac1 decode --batch DIR --jobs N`` against ``--jobs 1`` on the same archive, in one run.

Generates (``traffic.py``, seeded) an archive of ``--files`` captures of ``--exchanges`` exchanges each,
pcapng and socat ``-x`` alternately, every other one anomalous (a rule broken every tenth exchange), then
times ``xac1 decode --batch DIR --jobs 1`` and ``--jobs N`` (default: the cores), interleaved, best of
``--rounds``, each as a child process (wall time, its output discarded). Prints frames/s and the ratio
(issue 14: at least 1.8x on 2 cores).

Run: ``python benchmarks/bench_decode_batch.py [--files 16] [--exchanges 25000] [--keep DIR]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import traffic  # noqa: E402
from bench_decode_vs_tshark import CHILD_ENV  # noqa: E402


def archive(folder: Path, files: int, exchanges: int, seed: int) -> int:
    """Write the archive (files already there are kept: same seed, same bytes); returns its frames."""
    frames = 0
    for k in range(files):
        kind: traffic.Kind = "anomalous" if k % 4 >= 2 else "cell"
        suffix, writer = (".pcapng", traffic.write_pcapng) if k % 2 == 0 else (".log", traffic.write_socat)
        path = folder / f"capture-{k:02d}-{kind}{suffix}"
        if not path.exists():
            writer(traffic.conversation(exchanges, seed + k, kind), path)
        frames += sum(1 for _ in traffic.conversation(exchanges, seed + k, kind))
    return frames


def wall(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    code = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=CHILD_ENV).returncode
    seconds = time.perf_counter() - t0
    if code not in (0, 1):  # 1: violations found (the anomalous files)
        raise SystemExit(f"{' '.join(cmd)} exited {code}")
    return seconds


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--files", type=int, default=16)
    ap.add_argument("--exchanges", type=int, default=25_000)
    ap.add_argument("--jobs", type=int, default=len(os.sched_getaffinity(0)))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", type=Path, help="write the archive here and keep it")
    args = ap.parse_args(argv)
    xac1 = shutil.which("xac1") or str(Path(sys.executable).with_name("xac1"))
    folder = args.keep or Path(tempfile.mkdtemp(prefix="xac1-batch-"))
    folder.mkdir(parents=True, exist_ok=True)
    frames = archive(folder, args.files, args.exchanges, args.seed)
    best = {1: float("inf"), args.jobs: float("inf")}
    for _ in range(args.rounds):
        for jobs in best:
            best[jobs] = min(best[jobs], wall([xac1, "decode", "--batch", str(folder), "--jobs", str(jobs)]))
    print(f"{args.files} files of {args.exchanges} exchanges ({frames} frames) in {folder}, best of "
          f"{args.rounds}")
    for jobs, seconds in best.items():
        print(f"--jobs {jobs}: {seconds:6.2f} s  {frames / seconds:11,.0f} frames/s  "
              f"{best[1] / seconds:5.2f}x --jobs 1")
    if args.keep is None:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
