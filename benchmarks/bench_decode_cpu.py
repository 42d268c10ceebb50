"""Benchmark: the CPU time of ``xac1 decode`` of several checkouts on the same seeded files, interleaved.

On a shared machine wall time measures the neighbours; the CPU time a decode is charged (user + system,
from the child's resource usage) moves far less. Each ``--xac1`` is an ``xac1`` executable (this
environment's by default; another checkout's, to compare before and after); every round runs each of
them once on each file and view, one after the other, so a slow minute falls on all of them alike. The
best of ``--repeat`` rounds is kept, and the load average is printed with each round.

Run: ``python benchmarks/bench_decode_cpu.py --xac1 OLD/bin/xac1 NEW/bin/xac1 [--exchanges 100000]
[--kinds cell misbehaving] [--formats pcapng socat] [--views summary jsonl text] [--repeat 3]
[--keep DIR]``.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import traffic  # noqa: E402

SUFFIXES = {"pcapng": ".pcapng", "socat": ".log"}
VIEWS = {"summary": ["--format", "summary"], "jsonl": ["--format", "jsonl"], "text": []}
CHILD_ENV = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "PYTHONUNBUFFERED")}


def cpu_seconds(cmd: list[str]) -> float:
    """User + system CPU seconds of one run of ``cmd`` (output discarded)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    code = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=CHILD_ENV).returncode
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if code not in (0, 1):  # 1: violations found
        raise SystemExit(f"{' '.join(cmd)} exited {code}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def traffic_file(workdir: Path, kind: traffic.Kind, fmt: str, exchanges: int, seed: int) -> Path:
    """The seeded file of this traffic (written unless already there: same seed, same bytes)."""
    path = workdir / f"{kind}-{exchanges}-seed{seed}{SUFFIXES[fmt]}"
    if not path.exists():
        traffic.WRITERS[fmt](traffic.conversation(exchanges, seed, kind), path)
    return path


def _quiet(xac1: str) -> list[str]:
    """``--no-progress`` where that checkout's decode has it."""
    out = subprocess.run([xac1, "decode", "--help"], capture_output=True, text=True).stdout
    return ["--no-progress"] if "--no-progress" in out else []


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    beside = Path(sys.executable).with_name("xac1")
    ap.add_argument("--xac1", nargs="+", default=[str(beside)], help="the xac1 executables to compare")
    ap.add_argument("--exchanges", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--kinds", nargs="+", choices=traffic.KINDS, default=["cell"])
    ap.add_argument("--formats", nargs="+", choices=tuple(SUFFIXES), default=["pcapng"])
    ap.add_argument("--views", nargs="+", choices=tuple(VIEWS), default=list(VIEWS))
    ap.add_argument("--repeat", type=int, default=3, help="rounds, the best of each kept (default 3)")
    ap.add_argument("--keep", type=Path, help="write the generated files here and keep them (reused)")
    args = ap.parse_args(argv)
    workdir = args.keep or Path(tempfile.mkdtemp(prefix="xac1-bench-"))
    workdir.mkdir(parents=True, exist_ok=True)
    best: dict[tuple[str, str, str, str], float] = {}
    try:
        files = [(kind, fmt, traffic_file(workdir, kind, fmt, args.exchanges, args.seed))
                 for kind in args.kinds for fmt in args.formats]
        quiet = {xac1: _quiet(xac1) for xac1 in args.xac1}
        for round_ in range(1, args.repeat + 1):
            print(f"round {round_}: load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}",
                  file=sys.stderr, flush=True)
            for kind, fmt, path in files:
                for view in args.views:
                    for xac1 in args.xac1:
                        seconds = cpu_seconds([xac1, "decode", str(path), *quiet[xac1], *VIEWS[view]])
                        key = (kind, fmt, view, xac1)
                        best[key] = min(seconds, best.get(key, seconds))
    finally:
        if args.keep is None:
            shutil.rmtree(workdir, ignore_errors=True)
    print(f"{args.exchanges} exchanges a file, seed {args.seed}, CPU seconds, best of {args.repeat}; "
          f"ratio to the first xac1")
    print("| traffic | file | view | " + " | ".join(args.xac1) + " |")
    print("|---|---|---|" + "---:|" * len(args.xac1))
    for kind, fmt, _ in files:
        for view in args.views:
            first = best[(kind, fmt, view, args.xac1[0])]
            cells = [f"{best[(kind, fmt, view, x)]:.2f} ({best[(kind, fmt, view, x)] / first:.2f})"
                     for x in args.xac1]
            print(f"| {kind} | {fmt} | {view} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
