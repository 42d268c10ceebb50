"""Benchmark: framing and decoding throughput, as ratios to a bare line split of the same bytes.

Run on demand: ``python benchmarks/bench_codec.py [--frames N]``. Reports frames per second of the
framer alone, framer + strict ``parse``, framer + lenient ``diagnose``, and each one's cost as a
multiple of ``bytes.split(b"\\n")`` over the same stream (the floor any Python framer compares to).
"""

from __future__ import annotations

import argparse
import contextlib
import random
import time

import xac1_proto as x


def stream(n: int, seed: int = 1) -> bytes:
    rng = random.Random(seed)
    frames = [
        x.ReadPoint(n=3), x.ReadPointAnswer(n=3, v=9, a=3, o=0, pos=0x12345), x.ReadCurrent(),
        x.MoveDirect(vel=30, a=2, pos=5000), x.MoveDirectAnswer(vel=30, a=2, pos=5000),
        x.ReadOutputsAnswer(o=3), x.ReadVersionAnswer(version="100"), x.AlarmAnswer(code=1),
    ]
    wires = [f.to_bytes() for f in frames]
    return b"".join(rng.choice(wires) for _ in range(n))


def best(fn, data: bytes, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(data)
        times.append(time.perf_counter() - t0)
    return min(times)


def split_only(data: bytes) -> None:
    data.split(b"\n")


def framer_only(data: bytes) -> None:
    framer = x.Framer()
    for i in range(0, len(data), 4096):
        framer.feed(data[i: i + 4096], 0.0)
    framer.flush()


def with_decoder(decode):
    def run(data: bytes) -> None:
        framer = x.Framer()
        for i in range(0, len(data), 4096):
            for ev in framer.feed(data[i: i + 4096], 0.0):
                if isinstance(ev, x.FrameBytes):
                    decode(ev.raw, "answer" if len(ev.raw) > 6 else "command")
        framer.flush()
    return run


def strict(raw: bytes, role: str) -> None:
    with contextlib.suppress(x.FrameError):
        x.parse(raw, role)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=50_000)
    n = ap.parse_args().frames
    data = stream(n)
    base = best(split_only, data)
    print(f"{n} frames, {len(data)} bytes; baseline bytes.split: {n / base:,.0f} frames/s")
    for name, fn in [("framer", framer_only), ("framer+parse", with_decoder(strict)),
                     ("framer+diagnose", with_decoder(x.diagnose))]:
        t = best(fn, data, repeat=1 if "+" in name else 3)
        print(f"{name:>16}: {n / t:>12,.0f} frames/s  ({t / base:,.0f}x the baseline's time)")


if __name__ == "__main__":
    main()
