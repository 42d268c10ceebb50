"""Seeded XA-C1 field traffic for the decode benchmarks: a production cell, random field values, anomalies.

``conversation(n, seed, kind)`` yields the ``Chunk``s of ``n`` exchanges, one chunk a frame, each stamped
when its last byte is in (as a capture stamps a read). A scripted host sends each command once the
previous answer is in (1-5 ms later); the device is the project's simulator model
(``xac1_proto.sim.model.DeviceModel``, clean, docs/protocol.md's defaults), so every answer is what a
clean device answers, after a turnaround of 1-3 ms plus the answer's wire time at 9600 baud, and a move's
answer after the move's time (``xac1_proto.motion``: homing first, trapezoidal profile). Kinds:

- ``cell``: a production cell. The host reads the version, homes the axis and teaches 8 points (0WP),
  then loops over its job route: a move to the next point (0MP), the position polled (0RC, once or twice:
  the device cannot talk during a move, so polls come after it), the outputs polled (0RS) and one output
  toggled (0WS); now and then a point read back (0RP) or a move to a free position (0MV) then polled.
  Values vary as a real cell's do: the position with every move, the outputs with every toggle and move.
- ``random``: every exchange carries fresh field values: points written with random values, then read
  back or moved to, outputs set to random values and read back, moves to random positions, all polled.
- ``anomalous``: the cell's traffic with a rule broken every tenth exchange, cycling through the faults
  of ``_anomaly`` (a silence becomes a garbled answer on a move: a move's silence would hold every later
  command as sent during the move).
- ``misbehaving``: the capture a debugger reads (issue 35): the cell's traffic, its device's alarm
  (``MISBEHAVING_ALARM``, 09) raised at exchange ``MISBEHAVE_AT``; the host ignores it and goes on
  with its route, and the device answers the alarm once, then forgets it (the simulator's
  ``alarm-not-latched`` deviation) and answers as before: every later exchange is ``alarm-ignored`` on
  the host line and ``latch-broken`` on the device's, with the cell's varying values.
- ``storm``: the cell's host flooding communication errors: from exchange ``MISBEHAVE_AT`` every command
  has a stray space before its CR LF (a bad length); the clean device answers each ``0%%01`` (and holds
  alarm 01), so once ``spec.STORM_LIMIT`` of them are in a row every later command is also
  ``comm-error-storm``. The commands carry the cell's varying values.

Frames are built with the frame classes, never written by hand. Writers: socat ``-x`` dump and
RTAC-serial pcapng (``sniffer.io.pcap.PcapngWriter``).

Run: ``python benchmarks/traffic.py OUT --exchanges N --kind cell|random|anomalous|misbehaving|storm
--format socat|pcapng``.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
import time
from collections.abc import Callable, Generator, Iterator
from pathlib import Path
from typing import Final, Literal, get_args

from xac1_proto import frames as fr
from xac1_proto import spec
from xac1_proto.chunk import DEVICE, HOST, Chunk
from xac1_proto.codec import parse
from xac1_proto.sim.config import SimConfig
from xac1_proto.sim.model import DeviceModel

Kind = Literal["cell", "random", "anomalous", "misbehaving", "storm"]
KINDS: Final[tuple[Kind, ...]] = get_args(Kind)
START: Final = 1_790_000_000.0  # a fixed epoch: files are byte-identical for a seed
STROKE: Final = 0x030000  # pulses the scripted hosts move within (196,608: a 2 m axis at 0.01 mm)
TAUGHT: Final = 8  # points the cell teaches
FAULTS: Final = 6  # kinds of fault ``_anomaly`` cycles through
MISBEHAVE_AT: Final = 20  # the exchange from which the misbehaving and storm hosts misbehave (set-up done)
MISBEHAVING_ALARM: Final = spec.ALARM_LIMIT  # the alarm the misbehaving host ignores (09, a limit)

# A host script yields commands and is sent each command's answer (docs/protocol.md "Framing": one
# command, then its answer).
Host = Generator[fr.Frame, fr.Frame, None]


def _point(rng: random.Random, n: int, slowest: int) -> fr.WritePoint:
    return fr.WritePoint(n=n, v=rng.randint(slowest, 9), a=rng.randint(1, 3), o=rng.randint(0, 3),
                         pos=rng.randint(0, STROKE))


def _free_move(rng: random.Random) -> fr.MoveDirect:
    return fr.MoveDirect(vel=rng.randint(10, 60), a=rng.randint(1, 3), pos=rng.randint(0, STROKE))


def cell_host(rng: random.Random) -> Host:
    """A production cell's host: set-up, then its job route for ever (see the module docstring)."""
    yield fr.ReadVersion()
    yield fr.MovePoint(n=0)  # homing
    for n in range(1, TAUGHT + 1):
        yield _point(rng, n, slowest=4)
    route = list(range(1, TAUGHT + 1))
    rng.shuffle(route)
    while True:
        for n in route:
            yield fr.MovePoint(n=n)
            for _ in range(rng.choice((1, 1, 2))):
                yield fr.ReadCurrent()
            outputs = yield fr.ReadOutputs()
            o = outputs.o if isinstance(outputs, fr.ReadOutputsAnswer) else 0
            yield fr.WriteOutputs(o=o ^ rng.choice((1, 2)))
            if rng.random() < 0.15:
                yield fr.ReadPoint(n=rng.randint(1, TAUGHT))
            if rng.random() < 0.15:
                yield _free_move(rng)
                yield fr.ReadCurrent()


def random_host(rng: random.Random) -> Host:
    """A host whose every exchange carries fresh field values (see the module docstring)."""
    yield fr.MovePoint(n=0)
    while True:
        step = rng.randrange(4)
        if step == 0:  # a new point, read back
            point = _point(rng, rng.randint(1, 15), slowest=1)
            yield point
            yield fr.ReadPoint(n=point.n)
        elif step == 1:
            yield fr.WriteOutputs(o=rng.randint(0, 3))
            yield fr.ReadOutputs()
        elif step == 2:
            yield fr.MoveDirect(vel=rng.randint(1, 60), a=rng.randint(1, 3), pos=rng.randint(0, STROKE))
            yield fr.ReadCurrent()
        else:  # a new point, moved to (its O becomes the outputs)
            point = _point(rng, rng.randint(1, 15), slowest=1)
            yield point
            yield fr.MovePoint(n=point.n)
            yield fr.ReadCurrent()
            yield fr.ReadOutputs()


HOSTS: Final[dict[Kind, Callable[[random.Random], Host]]] = {
    "cell": cell_host, "random": random_host, "anomalous": cell_host, "misbehaving": cell_host,
    "storm": cell_host}
# kind -> the simulator's deviations (``xac1_proto.sim.config.DEVIATIONS``) its device shows
DEVIATIONS: Final[dict[Kind, frozenset[str]]] = {"misbehaving": frozenset({"alarm-not-latched"})}


def _anomaly(k: int, command: bytes, answer: bytes, move: bool) -> tuple[bytes, bytes | None]:
    """The k-th fault: (command bytes, answer bytes or None for silence)."""
    kind = k % FAULTS
    if kind == 1 and move:
        kind = 2
    if kind == 0:  # letter O from the host; the device still answers
        return spec.LETTER_O + command[1:], answer
    if kind == 1:  # no answer
        return command, None
    if kind == 2:  # a garbled answer byte
        return command, answer[:4] + b"\xff" + answer[5:]
    if kind == 3:  # an answer without the terminator's CR
        return command, answer[:-2] + b"\n"
    if kind == 4:  # lower-case hex in the command
        return command.lower(), answer
    return command, answer[:-2] + b" " + answer[-2:]  # bad length


def conversation(n: int, seed: int = 1, kind: Kind = "cell") -> Iterator[Chunk]:
    """``n`` exchanges of traffic of ``kind`` as chunks in time order."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    rng = random.Random(seed)
    # the turnaround is drawn below, per answer
    device = DeviceModel(SimConfig(turnaround_s=0.0, deviations=DEVIATIONS.get(kind, frozenset())))
    host = HOSTS[kind](rng)
    command = next(host)
    t = START
    for i in range(n):
        c = command.to_bytes()
        if i == MISBEHAVE_AT and kind == "misbehaving":
            device.raise_alarm(MISBEHAVING_ALARM, t)
        elif i >= MISBEHAVE_AT and kind == "storm":
            c = c[:-2] + b" " + c[-2:]  # a bad length: the device answers 0%%01
        t += len(c) * spec.BYTE_TIME_S
        (out,) = device.receive(c, t)
        device.outbox.pop(math.inf)  # sent: the outbox keeps nothing
        a: bytes | None = out.data
        if kind == "anomalous" and i % 10 == 9:
            c, a = _anomaly(i // 10, c, out.data, command.header in spec.MOVE_HEADERS)
        yield Chunk(t, HOST, c)
        turnaround = rng.uniform(0.001, 0.003)  # drawn for a silence too: the same host follows
        if a is None:
            t = out.due + spec.NO_ANSWER_TIMEOUT_S + 0.5
        else:
            t = out.due + turnaround + len(a) * spec.BYTE_TIME_S
            yield Chunk(t, DEVICE, a)
        t += rng.uniform(0.001, 0.005)
        command = host.send(parse(out.data, spec.ANSWER))


def write_socat(chunks: Iterator[Chunk], path: Path) -> None:
    """socat ``-x`` dump: a header (local time, as socat writes it) and one hex line a transfer; host is
    ``>``."""
    count = {HOST: 0, DEVICE: 0}
    with open(path, "w", encoding="ascii") as f:
        for ch in chunks:
            t = ch.t or START
            stamp = time.strftime("%Y/%m/%d %H:%M:%S", time.localtime(t)) + f".{int(t % 1 * 1e6):06d}"
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


WRITERS: Final = {"socat": write_socat, "pcapng": write_pcapng}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--exchanges", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--kind", choices=KINDS, default="cell",
                    help="cell (default), random (fresh values every exchange), anomalous (cell traffic, "
                         "a rule broken every tenth exchange), misbehaving (a host that ignored an alarm), "
                         "storm (a host flooding communication errors)")
    ap.add_argument("--format", choices=tuple(WRITERS), default=None,
                    help="default: from the suffix (.pcapng, else socat)")
    args = ap.parse_args(argv)
    fmt = args.format or ("pcapng" if args.out.suffix == ".pcapng" else "socat")
    WRITERS[fmt](conversation(args.exchanges, args.seed, args.kind), args.out)
    print(f"{args.out}: {args.exchanges} exchanges of {args.kind} traffic, "
          f"{args.out.stat().st_size / 1e6:.1f} MB ({fmt})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
