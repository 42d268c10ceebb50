"""Benchmark: ``xac1 decode`` against tshark with a Lua dissector, on the same seeded files, in one run.

Generates (``traffic.py``) a clean and an anomalous conversation of ``--exchanges`` exchanges as an
RTAC-serial pcapng and a socat ``-x`` log, then times, each as a child process (wall time, and the
peak RSS of that child alone, from ``peak_rss.py``; the best of ``--repeat`` runs, the file read once
just before each):
- ``xac1 decode FILE --format summary``, ``--format jsonl`` and the text view (to /dev/null);
- ``tshark -r FILE.pcapng -X lua_script:<dissector> -d rtacser.data,<proto> -T fields -e <field>``
  with ``minimal_dissector.lua`` (the issue's peer), or ``--dissector PATH PROTO FIELD``;
and the library path in this process (``sniffer.analyzer.Analyzer.feed_many``, records made: the path the
live sniffer and decode share), with the reader and from chunks already read. Prints frames/s, MB/s,
peak RSS and each ratio to tshark (the socat log's rows too: it holds the same frames as the pcapng).

Run: ``python benchmarks/bench_decode_vs_tshark.py [--exchanges 500000] [--keep DIR]``.
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
from typing import TYPE_CHECKING

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import traffic  # noqa: E402

if TYPE_CHECKING:
    from sniffer.records import Record
    from xac1_proto.chunk import Chunk
from peak_rss import run_measuring_peak_rss  # noqa: E402

# The children run as an installed tool does: compiled modules cached (an environment that forbids
# writing them would make every run compile the package) and stdout buffered.
CHILD_ENV = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "PYTHONUNBUFFERED")}


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


def library_path(path: Path, fmt: str) -> tuple[float, float]:
    """Seconds of the library path in this process, records made (and dropped), best of three:
    (the reader and ``Analyzer.feed_many``, the chunks already read and ``Analyzer.feed_many``)."""
    from sniffer.analyzer import Analyzer
    from sniffer.io.registry import Capture

    def analyze(chunks: Iterable[Chunk]) -> float:
        t0 = time.perf_counter()
        analyzer = Analyzer()
        it = iter(chunks)
        records: list[Record] = []
        while analyzer.feed_many(it, records):
            records = []
        analyzer.close()
        return time.perf_counter() - t0

    fmt = "pcap" if fmt == "pcapng" else fmt
    with_reader = []
    for _ in range(3):
        warm(path)
        with Capture([str(path)], fmt) as capture:
            with_reader.append(analyze(capture))
    warm(path)
    with Capture([str(path)], fmt) as capture:
        chunks = list(capture)
    return min(with_reader), min(analyze(chunks) for _ in range(3))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exchanges", type=int, default=500_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each command, the best kept (default 3)")
    ap.add_argument("--keep", type=Path, help="write the generated files here and keep them")
    ap.add_argument("--dissector", nargs=3, metavar=("LUA", "PROTO", "FIELD"),
                    default=[str(HERE / "minimal_dissector.lua"), "xac1min", "xac1min.header"])
    args = ap.parse_args(argv)
    xac1 = shutil.which("xac1") or str(Path(sys.executable).with_name("xac1"))
    tshark = shutil.which("tshark")
    workdir = args.keep or Path(tempfile.mkdtemp(prefix="xac1-bench-"))
    workdir.mkdir(parents=True, exist_ok=True)
    frames_per = {}
    rows = []
    for anomalous in (False, True):
        kind = "anomalous" if anomalous else "clean"
        peer = None  # tshark's seconds on this traffic's pcapng (the socat log holds the same frames)
        for fmt, writer, suffix in (("pcapng", traffic.write_pcapng, ".pcapng"),
                                    ("socat", traffic.write_socat, ".log")):
            path = workdir / f"{kind}-{args.exchanges}{suffix}"
            if not path.exists():
                writer(traffic.conversation(args.exchanges, args.seed, anomalous), path)
            n = sum(1 for _ in traffic.conversation(args.exchanges, args.seed, anomalous))
            frames_per[path] = n
            mb = path.stat().st_size / 1e6
            if fmt == "pcapng" and tshark:
                lua, proto, field = args.dissector
                wall, rss = run([tshark, "-r", str(path), "-X", f"lua_script:{lua}", "-d",
                                 f"rtacser.data,{proto}", "-T", "fields", "-e", field], path, args.repeat)
                peer = wall
                rows.append((kind, fmt, "tshark + Lua", n / wall, mb / wall, rss, 1.0))
            for label, extra in (("decode summary", ["--format", "summary"]),
                                 ("decode jsonl", ["--format", "jsonl"]),
                                 ("decode text", [])):
                wall, rss = run([xac1, "decode", str(path), "--no-progress", *extra]
                                if _has_no_progress(xac1) else [xac1, "decode", str(path), *extra], path,
                                args.repeat)
                ratio = None if peer is None else peer / wall
                rows.append((kind, fmt, label, n / wall, mb / wall, rss, ratio))
            for label, wall in zip(("library + reader", "library path"), library_path(path, fmt),
                                   strict=True):
                rows.append((kind, fmt, label, n / wall, mb / wall, float("nan"),
                             None if peer is None else peer / wall))
    print(f"{args.exchanges} exchanges a file, seed {args.seed}, files in {workdir}, best of {args.repeat}")
    print(f"{'traffic':10} {'file':7} {'what':16} {'frames/s':>11} {'MB/s':>7} {'peak MiB':>9} "
          f"{'x tshark':>9}")
    for kind, fmt, label, fps, mbs, rss, ratio in rows:
        shown = "-" if ratio is None else f"{ratio:.2f}"
        rss_s = "-" if rss != rss else f"{rss:.0f}"
        print(f"{kind:10} {fmt:7} {label:16} {fps:11,.0f} {mbs:7.2f} {rss_s:>9} {shown:>9}")
    if args.keep is None:
        shutil.rmtree(workdir, ignore_errors=True)
    return 0


def _has_no_progress(xac1: str) -> bool:
    out = subprocess.run([xac1, "decode", "--help"], capture_output=True, text=True).stdout
    return "--no-progress" in out


if __name__ == "__main__":
    raise SystemExit(main())
