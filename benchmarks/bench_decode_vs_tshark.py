"""Benchmark: ``xac1 decode`` against tshark with a Lua dissector, on the same seeded files, in one run.

Generates (``traffic.py``, seeded) each kind of field traffic (``cell``: a production cell, ``random``:
fresh field values in every exchange, ``anomalous``: the cell with a rule broken every tenth exchange,
``misbehaving``: a host that ignored an alarm, every later exchange judged, ``storm``: a host flooding
communication errors)
as an RTAC-serial pcapng and a socat ``-x`` log of ``--exchanges`` exchanges (the default, 500,000,
is about 1,000,000 frames), then times, each as a child process (wall time, and the peak RSS of that child
alone, from ``peak_rss.py``; the best of ``--repeat`` runs, the file read once just before each):
- ``tshark -r FILE.pcapng -X lua_script:<dissector> -d rtacser.data,<proto> -T fields -e <field>``
  with ``minimal_dissector.lua`` (the issue's peer), or ``--dissector PATH PROTO FIELD``;
- ``xac1 decode FILE --format summary``, ``--format jsonl`` and the text view (to /dev/null);
and the library path in this process (``sniffer.analyzer.Analyzer.feed_many``, records made: the path the
live sniffer and decode share), with the reader and from chunks already read. Prints frames/s, MB/s,
peak RSS and each row's ratio to tshark on the pcapng of the same traffic, measured in the same run (the
socat log holds the same frames as the pcapng). ``--markdown`` prints the table for benchmarks/README.md.

Run: ``python benchmarks/bench_decode_vs_tshark.py [--exchanges 500000] [--kinds cell random anomalous]
[--formats pcapng socat] [--repeat 3] [--keep DIR]``; ``--exchanges 20000 --repeat 1`` for a quick look.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import traffic  # noqa: E402
from peak_rss import run_measuring_peak_rss  # noqa: E402

if TYPE_CHECKING:
    from xac1_proto.chunk import Chunk

# The children run as an installed tool does: compiled modules cached (an environment that forbids
# writing them would make every run compile the package) and stdout buffered.
CHILD_ENV = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "PYTHONUNBUFFERED")}
SUFFIXES = {"pcapng": ".pcapng", "socat": ".log"}
DECODES: tuple[tuple[str, list[str]], ...] = (
    ("decode summary", ["--format", "summary"]), ("decode jsonl", ["--format", "jsonl"]), ("decode text", []))


class Row(NamedTuple):
    kind: str
    fmt: str
    what: str
    frames_s: float
    mb_s: float
    peak_mib: float | None  # None: measured in this process (no peak of its own)
    ratio: float | None  # to tshark on the same traffic's pcapng; None without tshark


def warm(path: Path) -> None:
    """Read the file once, so that each command reads it from the page cache (a virtual machine may drop
    a file's pages within a minute: the first reader after that would also pay for the disk)."""
    with open(path, "rb") as f:
        while f.read(1 << 20):
            pass


def run(cmd: list[str], path: Path, repeat: int = 1) -> tuple[float, float]:
    """(wall seconds, peak RSS MiB) of a child process reading ``path``, its output discarded: the best
    wall time and the largest peak of ``repeat`` runs (a shared virtual machine has slow moments)."""
    walls, peaks = [], []
    for _ in range(repeat):
        warm(path)
        t0 = time.perf_counter()
        code, peak_mib = run_measuring_peak_rss(cmd, env=CHILD_ENV)
        walls.append(time.perf_counter() - t0)
        peaks.append(peak_mib)
        if code not in (0, 1):  # 1: violations found (the anomalous files)
            raise SystemExit(f"{' '.join(cmd)} exited {code}")
    return min(walls), max(peaks)


def library_path(path: Path, fmt: str, repeat: int) -> tuple[float, float]:
    """Seconds of the library path in this process, records made (and dropped), best of ``repeat``:
    (the reader and ``Analyzer.feed_many``, the chunks already read and ``Analyzer.feed_many``)."""
    from sniffer.analyzer import Analyzer
    from sniffer.io.registry import Capture

    def analyze(chunks: Iterable[Chunk]) -> float:
        t0 = time.perf_counter()
        analyzer = Analyzer()
        it = iter(chunks)
        records: list[Any] = []  # records (the analyzer's own types)
        while analyzer.feed_many(it, records):
            records = []
        analyzer.close()
        return time.perf_counter() - t0

    fmt = "pcap" if fmt == "pcapng" else fmt
    with_reader = []
    for _ in range(repeat):
        warm(path)
        with Capture([str(path)], fmt) as capture:
            with_reader.append(analyze(capture))
    warm(path)
    with Capture([str(path)], fmt) as capture:
        chunks = list(capture)
    return min(with_reader), min(analyze(chunks) for _ in range(repeat))


def traffic_file(workdir: Path, kind: traffic.Kind, fmt: str, exchanges: int, seed: int) -> tuple[Path, int]:
    """The seeded file of this traffic (written unless already there: same seed, same bytes), its frames."""
    path = workdir / f"{kind}-{exchanges}-seed{seed}{SUFFIXES[fmt]}"
    if not path.exists():
        traffic.WRITERS[fmt](traffic.conversation(exchanges, seed, kind), path)
    return path, sum(1 for _ in traffic.conversation(exchanges, seed, kind))


def measure(args: argparse.Namespace, workdir: Path) -> list[Row]:
    """Every row, each printed (to stderr) as soon as it is measured: a long run's rows are not lost."""
    rows = _Rows()
    beside = Path(sys.executable).with_name("xac1")  # this environment's, before any other on PATH
    xac1 = str(beside) if beside.exists() else shutil.which("xac1") or "xac1"
    tshark = None if args.no_tshark else shutil.which("tshark")
    for kind in args.kinds:
        peer = None  # tshark's seconds on this traffic's pcapng (the socat log holds the same frames)
        pcapng, n = traffic_file(workdir, kind, "pcapng", args.exchanges, args.seed)
        if tshark:
            lua, proto, field = args.dissector
            wall, rss = run([tshark, "-r", str(pcapng), "-X", f"lua_script:{lua}", "-d",
                             f"rtacser.data,{proto}", "-T", "fields", "-e", field], pcapng, args.repeat)
            peer = wall
            rows.append(Row(kind, "pcapng", "tshark + Lua", n / wall, _mb(pcapng) / wall, rss, 1.0))
        for fmt in args.formats:
            path, n = traffic_file(workdir, kind, fmt, args.exchanges, args.seed)
            for label, extra in DECODES:
                wall, rss = run([xac1, "decode", str(path), *_quiet(xac1), *extra], path, args.repeat)
                rows.append(Row(kind, fmt, label, n / wall, _mb(path) / wall, rss, _ratio(peer, wall)))
            if not args.no_library:
                for label, wall in zip(("library + reader", "library path"),
                                       library_path(path, fmt, args.repeat), strict=True):
                    rows.append(Row(kind, fmt, label, n / wall, _mb(path) / wall, None, _ratio(peer, wall)))
    return rows


class _Rows(list[Row]):
    """The rows measured, each printed to stderr as it comes."""

    def append(self, row: Row) -> None:
        super().append(row)
        print("measured:", *row, file=sys.stderr, flush=True)


def _mb(path: Path) -> float:
    return path.stat().st_size / 1e6


def _ratio(peer: float | None, wall: float) -> float | None:
    return None if peer is None else peer / wall


def _quiet(xac1: str) -> list[str]:
    out = subprocess.run([xac1, "decode", "--help"], capture_output=True, text=True).stdout
    return ["--no-progress"] if "--no-progress" in out else []


def show(rows: list[Row], markdown: bool) -> None:
    if markdown:
        print("| traffic | file | what | frames/s | MB/s | peak MiB | x tshark + minimal Lua |")
        print("|---|---|---|---:|---:|---:|---:|")
    else:
        print(f"{'traffic':10} {'file':7} {'what':16} {'frames/s':>11} {'MB/s':>7} {'peak MiB':>9} "
              f"{'x tshark':>9}")
    for r in rows:
        ratio = "-" if r.ratio is None else f"{r.ratio:.2f}"
        peak = "-" if r.peak_mib is None else f"{r.peak_mib:.0f}"
        if markdown:
            print(f"| {r.kind} | {r.fmt} | {r.what} | {r.frames_s:,.0f} | {r.mb_s:.2f} | {peak} | {ratio} |")
        else:
            print(f"{r.kind:10} {r.fmt:7} {r.what:16} {r.frames_s:11,.0f} {r.mb_s:7.2f} {peak:>9} "
                  f"{ratio:>9}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exchanges", type=int, default=500_000,
                    help="exchanges a file (default 500,000: about 1,000,000 frames, the issue's size)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--kinds", nargs="+", choices=traffic.KINDS, default=list(traffic.KINDS))
    ap.add_argument("--formats", nargs="+", choices=tuple(SUFFIXES), default=list(SUFFIXES))
    ap.add_argument("--repeat", type=int, default=3, help="runs of each command, the best kept (default 3)")
    ap.add_argument("--keep", type=Path, help="write the generated files here and keep them (reused)")
    ap.add_argument("--no-library", action="store_true", help="leave out the in-process library rows")
    ap.add_argument("--no-tshark", action="store_true", help="leave out tshark (no ratios)")
    ap.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    ap.add_argument("--dissector", nargs=3, metavar=("LUA", "PROTO", "FIELD"),
                    default=[str(HERE / "minimal_dissector.lua"), "xac1min", "xac1min.header"])
    args = ap.parse_args(argv)
    workdir = args.keep or Path(tempfile.mkdtemp(prefix="xac1-bench-"))
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        rows = measure(args, workdir)
    finally:
        if args.keep is None:
            shutil.rmtree(workdir, ignore_errors=True)
    print(f"{args.exchanges} exchanges a file, seed {args.seed}, best of {args.repeat}"
          + (f", files in {args.keep}" if args.keep else ""))
    show(rows, args.markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
