"""Benchmark: ``xac1 decode`` memory on a large socat log, as a ratio to a small one.

Run on demand: ``python benchmarks/bench_decode_memory.py [--mb 50]``. Writes a ``socat -x`` log of
the gallery's faultless conversation repeated (``captures/make_gallery.py: write_large_socat``) of
1 MB and of ``--mb`` MB, decodes each in a child process (``--format summary``) and reports each
child's peak resident memory (``peak_rss.py``: the child's alone) and the ratio. The readers stream,
so the ratio stays near 1 and the peak under 64 MiB whatever the size; exits 1 when it passes that.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

from peak_rss import run_measuring_peak_rss  # this script's directory is on sys.path

ROOT = Path(__file__).resolve().parent.parent
LIMIT_MB = 64  # issue 14: at most 64 MiB for any input size


def _gallery():
    spec = importlib.util.spec_from_file_location("make_gallery", ROOT / "captures" / "make_gallery.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def decode_peak(path: Path) -> tuple[float, float]:
    """(peak RSS in MB, seconds) of ``xac1 decode --format summary PATH`` in a child process."""
    t0 = time.perf_counter()
    code, peak_mib = run_measuring_peak_rss(
        [sys.executable, "-m", "xac1_proto", "decode", "--format", "summary", str(path)], cwd=ROOT)
    if code != 0:
        raise SystemExit(f"decode of {path} exited {code}")
    return peak_mib, time.perf_counter() - t0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mb", type=float, default=50.0, help="size of the large log in MB (default 50)")
    args = p.parse_args()
    gallery = _gallery()
    with tempfile.TemporaryDirectory() as tmp:
        small, large = Path(tmp) / "small.log", Path(tmp) / "large.log"
        gallery.write_large_socat(small, 1_000_000)
        size = gallery.write_large_socat(large, int(args.mb * 1_000_000))
        small_mb, small_s = decode_peak(small)
        large_mb, large_s = decode_peak(large)
    print(f"1 MB log: peak RSS {small_mb:.1f} MiB ({small_s:.1f} s)")
    print(f"{size / 1e6:.0f} MB log: peak RSS {large_mb:.1f} MiB ({large_s:.1f} s, "
          f"{size / 1e6 / large_s:.1f} MB/s)")
    print(f"ratio: {large_mb / small_mb:.2f}x the memory for {size / 1_000_000:.0f}x the data "
          f"(target: <= {LIMIT_MB} MiB)")
    return 0 if large_mb <= LIMIT_MB else 1


if __name__ == "__main__":
    sys.exit(main())
