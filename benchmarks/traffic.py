"""Seeded XA-C1 traffic for the decode benchmarks: clean and anomalous conversations, as files.

``conversation(n, seed, anomalous)`` yields ``Chunk``s of ``n`` exchanges: a host command, then the
device's answer after a turnaround of 1-3 ms plus wire time at 9600 baud. Clean traffic mixes every
command of the frame table with its well-formed answer (values kept consistent, so no read-back
differs). Anomalous traffic breaks a rule every tenth exchange, cycling through the faults below, so a
decoder's slow paths are exercised at a steady rate. Frames are built with the frame classes, never
written by hand. Writers: socat ``-x`` dump and RTAC-serial pcapng (``sniffer.io.pcap.PcapngWriter``).

Run: ``python benchmarks/traffic.py OUT --exchanges N [--anomalous] [--format socat|pcapng]``.
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from xac1_proto import frames as fr
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk

START = 1_790_000_000.0  # a fixed epoch: files are byte-identical for a seed


def _exchanges(rng: random.Random) -> list[tuple[fr.Frame, fr.Frame]]:
    """Command/answer pairs a well-behaved host and controller exchange (consistent values)."""
    points = {n: (rng.randint(1, 9), rng.randint(1, 3), rng.randint(0, 3), rng.randint(0, 0x3000))
              for n in range(1, 16)}
    pairs: list[tuple[fr.Frame, fr.Frame]] = []
    for n, (v, a, o, pos) in points.items():
        pairs.append((fr.ReadPoint(n=n), fr.ReadPointAnswer(n=n, v=v, a=a, o=o, pos=pos)))
        pairs.append((fr.WritePoint(n=n, v=v, a=a, o=o, pos=pos),
                      fr.WritePointAnswer(n=n, v=v, a=a, o=o, pos=pos)))
    pairs += [
        (fr.ReadVersion(), fr.ReadVersionAnswer(version="100")),
        (fr.ReadOutputs(), fr.ReadOutputsAnswer(o=0)),
        (fr.WriteOutputs(o=0), fr.WriteOutputsAnswer(o=0)),
        (fr.SwitchMode(mode=1), fr.SwitchModeAnswer(mode=1)),
    ]
    return pairs


def _anomaly(k: int, command: fr.Frame, answer: fr.Frame) -> tuple[bytes, bytes | None]:
    """The k-th fault: (command bytes, answer bytes or None for silence)."""
    c, a = command.to_bytes(), answer.to_bytes()
    kind = k % 6
    if kind == 0:  # letter O from the host; the device still answers
        return spec.LETTER_O + c[1:], a
    if kind == 1:  # no answer
        return c, None
    if kind == 2:  # a garbled answer byte
        return c, a[:4] + b"\xff" + a[5:]
    if kind == 3:  # an answer without the terminator's CR
        return c, a[:-2] + b"\n"
    if kind == 4:  # lower-case hex in the command
        return c.lower(), a
    return c, a[:-2] + b" " + a[-2:]  # bad length


def conversation(n: int, seed: int = 1, anomalous: bool = False) -> Iterator[Chunk]:
    """``n`` exchanges as chunks in time order."""
    rng = random.Random(seed)
    pairs = _exchanges(rng)
    t = START
    for i in range(n):
        command, answer = pairs[rng.randrange(len(pairs))]
        c, a = command.to_bytes(), answer.to_bytes()
        if anomalous and i % 10 == 9:
            c, maybe = _anomaly(i // 10, command, answer)
        else:
            maybe = a
        t += len(c) * spec.BYTE_TIME_S  # a capture stamps a read when its last byte is in
        yield Chunk(t, HOST, c)
        if maybe is None:
            t += spec.NO_ANSWER_TIMEOUT_S + 0.5
            continue
        t += rng.uniform(0.001, 0.003) + len(maybe) * spec.BYTE_TIME_S
        yield Chunk(t, DEVICE, maybe)
        t += rng.uniform(0.001, 0.005)


def write_socat(chunks: Iterator[Chunk], path: Path) -> None:
    """socat ``-x`` dump: a header and one hex line a transfer; host is ``>``."""
    count = {HOST: 0, DEVICE: 0}
    with open(path, "w", encoding="ascii") as f:
        for ch in chunks:
            t = ch.t or START
            stamp = time.strftime("%Y/%m/%d %H:%M:%S", time.gmtime(t)) + f".{int(t % 1 * 1e6):06d}"
            start = count[ch.dir]
            count[ch.dir] += len(ch.data)
            mark = ">" if ch.dir == HOST else "<"
            f.write(f"{mark} {stamp}  length={len(ch.data)} from={start} to={count[ch.dir] - 1}\n")
            f.write(" " + " ".join(f"{b:02x}" for b in ch.data) + "\n")


def write_pcapng(chunks: Iterator[Chunk], path: Path) -> None:
    """RTAC-serial pcapng, one packet a chunk (host TX, device RX)."""
    from sniffer.io.pcap import PcapngWriter

    with PcapngWriter(path) as w:
        for ch in chunks:
            w.write(ch)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--exchanges", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--anomalous", action="store_true", help="break a rule every tenth exchange")
    ap.add_argument("--format", choices=("socat", "pcapng"), default=None,
                    help="default: from the suffix (.pcapng, else socat)")
    args = ap.parse_args(argv)
    fmt = args.format or ("pcapng" if args.out.suffix == ".pcapng" else "socat")
    chunks = conversation(args.exchanges, args.seed, args.anomalous)
    (write_pcapng if fmt == "pcapng" else write_socat)(chunks, args.out)
    print(f"{args.out}: {args.exchanges} exchanges, {args.out.stat().st_size / 1e6:.1f} MB ({fmt})",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
