"""Benchmark: pty round trip of ``0RP3`` to the simulator in instant mode, as a ratio to a bare pty echo.

Both sides are the same shape: a thread holds a pty master and answers what a pyserial client writes on
the slave; the baseline thread echoes the bytes back untouched, the simulator parses the command, runs
the device model and builds the 16-byte answer. The figure that matters is the ratio of the medians
(target: at most 2x), not the absolute times, which depend on the machine.

``--panel``: the simulator runs with its front panel served beside it (``xac1 sim --panel``: every byte
tapped for the panel's line view, its server in its own thread), no browser connected.

Run: ``python benchmarks/bench_sim_pty.py [--rounds N] [--panel]``
"""

from __future__ import annotations

import argparse
import contextlib
import os
import select
import statistics
import threading
import time
import tty

import serial

from xac1_proto.sim import SimConfig, control, serve_pty

COMMAND = b"0RP3\r\n"


class EchoPty:
    """A pty whose master side echoes every byte back: the cheapest possible 'device'."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            ready, _, _ = select.select([self.master, self._stop_r], [], [])
            if self._stop_r in ready:
                return
            os.write(self.master, os.read(self.master, 4096))

    def close(self) -> None:
        os.write(self._stop_w, b"x")
        self._thread.join(5)
        for fd in (self.master, self.slave, self._stop_r, self._stop_w):
            os.close(fd)


def round_trips(path: str, rounds: int, answer_len: int) -> list[float]:
    times = []
    with serial.Serial(path, 9600, timeout=2) as port:
        for _ in range(rounds):
            t0 = time.perf_counter()
            port.write(COMMAND)
            got = port.read(answer_len)
            times.append(time.perf_counter() - t0)
            if len(got) != answer_len:
                raise RuntimeError(f"short answer {got!r}")
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2000)
    parser.add_argument("--panel", action="store_true", help="serve the front panel too (no browser)")
    args = parser.parse_args()

    echo = EchoPty()
    try:
        round_trips(echo.path, 100, len(COMMAND))  # warm-up
        base = round_trips(echo.path, args.rounds, len(COMMAND))
    finally:
        echo.close()
    with contextlib.ExitStack() as stack:
        panel = None
        if args.panel:
            from xac1_proto.sim.panel.server import Panel, panel_for

            panel = Panel()
        sim = stack.enter_context(serve_pty(SimConfig(time_scale=0), on_traffic=panel.tap if panel else None))
        if panel is not None:
            stack.enter_context(panel_for(sim, panel, control.ControlChannel(sim, panel.fact)))
        with serial.Serial(sim.path, 9600, timeout=2) as port:
            port.write(b"0WP39302012345\r\n")
            port.read(16)
        round_trips(sim.path, 100, 16)  # warm-up
        simulated = round_trips(sim.path, args.rounds, 16)
    b, s = statistics.median(base), statistics.median(simulated)
    print(f"bare pty echo      median {b * 1e6:8.1f} us  ({args.rounds} rounds)")
    served = ", front panel served" if args.panel else ""
    print(f"simulator 0RP3     median {s * 1e6:8.1f} us  (instant mode{served})")
    print(f"ratio simulator / echo: {s / b:.2f}x  (target <= 2x)")


if __name__ == "__main__":
    main()
