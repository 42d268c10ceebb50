"""Logic captures for the sigrok tests: simulator conversations drawn as two UART lines (9600 8N1) in a
VCD file that sigrok-cli reads, and sigrok-cli's annotations read back.

``converse`` plays a host script against the simulator's sans-IO model (``DeviceModel``) and returns
each line's bytes with the time of each byte's start bit; ``write_vcd`` draws them (idle high, start bit
low, 8 data bits LSB first, stop bit high, or low for a byte marked with a UART framing error) with a
1 µs timescale, so sigrok-cli sees channels ``host`` and ``device`` at 1 MHz.
"""

from __future__ import annotations

import os
import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from xac1_proto import spec
from xac1_proto.sim import DeviceModel, SimConfig

BIT_S = 1.0 / spec.BAUD
CHANNELS = ("host", "device")
TIMESCALE_HZ = 1_000_000  # the VCD's 1 us timescale: sigrok-cli's sample rate
LEAD_S = 0.005  # idle line before the capture's time 0
UART = f"uart:baudrate={spec.BAUD}:rx=device:tx=host"


@dataclass
class Line:
    """One UART line: (start-bit time, byte, framing error) for each byte, in order."""

    bytes_: list[tuple[float, int, bool]] = field(default_factory=list)

    def free_at(self) -> float:
        """When the line is idle again after its last byte (a damaged stop bit costs one idle bit)."""
        if not self.bytes_:
            return 0.0
        t, _, bad = self.bytes_[-1]
        return t + spec.BITS_PER_BYTE * BIT_S + (BIT_S if bad else 0.0)

    def send(self, t: float, data: bytes, bad: frozenset[int] = frozenset()) -> float:
        """Put ``data`` on the line from ``t`` (or when it is free); byte k of ``bad`` gets a framing
        error. Returns the end of the last stop bit."""
        at = max(t, self.free_at())
        for k, b in enumerate(data):
            self.bytes_.append((at, b, k in bad))
            at = self.free_at()
        return at

    @property
    def data(self) -> bytes:
        return bytes(b for _, b, _ in self.bytes_)


@dataclass
class Capture:
    host: Line = field(default_factory=Line)
    device: Line = field(default_factory=Line)


def converse(script: list[tuple[float, bytes] | tuple[float, bytes, frozenset[int]]],
             config: SimConfig | None = None, device_bad: dict[int, frozenset[int]] | None = None,
             device_split: dict[int, float] | None = None, alarms: dict[int, int] | None = None) -> Capture:
    """Play the host's writes ``(t, bytes[, bad byte indexes])`` against the simulator; its answers go
    on the device line when due. ``device_bad``: answer number -> indexes of its bytes to damage;
    ``device_split``: answer number -> a pause (s) in the middle of that answer; ``alarms``: step number
    -> an alarm the device raises just before that step."""
    model = DeviceModel(config or SimConfig(time_scale=0))
    cap = Capture()
    answers = 0
    for number, step in enumerate(script):
        t, data = step[0], step[1]
        if alarms and number in alarms:
            model.raise_alarm(alarms[number], t)
        bad = step[2] if len(step) == 3 else frozenset()  # type: ignore[misc]
        end = cap.host.send(t, data, bad)
        for out in model.receive(data, end):
            damaged = (device_bad or {}).get(answers, frozenset())
            pause = (device_split or {}).get(answers)
            if pause is None:
                cap.device.send(out.due, out.data, damaged)
            else:
                half = len(out.data) // 2
                mid = cap.device.send(out.due, out.data[:half], damaged)
                cap.device.send(mid + pause, out.data[half:],
                                frozenset(k - half for k in damaged if k >= half))
            answers += 1
    return cap


def _edges(line: Line) -> list[tuple[int, int]]:
    """(time in µs, level) of each change of the line."""
    out: list[tuple[int, int]] = []
    level = 1
    for t, b, bad in line.bytes_:
        bits = [0] + [(b >> i) & 1 for i in range(8)] + [0 if bad else 1]
        if bad:
            bits.append(1)  # back to idle after the damaged stop bit
        for k, bit in enumerate(bits):
            if bit != level:
                out.append((round((LEAD_S + t + k * BIT_S) * TIMESCALE_HZ), bit))
                level = bit
    return out


def write_vcd(path: Path, cap: Capture, tail_s: float = 0.01) -> Path:
    """The capture as a VCD with wires ``host`` and ``device`` (idle high before and after)."""
    ids = {"host": "!", "device": '"'}
    changes: dict[int, list[str]] = {}
    for name in CHANNELS:
        for t, level in _edges(getattr(cap, name)):
            changes.setdefault(t, []).append(f"{level}{ids[name]}")
    end = round((LEAD_S + max(cap.host.free_at(), cap.device.free_at()) + tail_s) * TIMESCALE_HZ)
    out = ["$timescale 1 us $end", "$scope module xac1 $end"]
    out += [f"$var wire 1 {ids[n]} {n} $end" for n in CHANNELS]
    out += ["$upscope $end", "$enddefinitions $end", "#0", "1!", '1"']
    for t in sorted(changes):
        out.append(f"#{t}")
        out += changes[t]
    out.append(f"#{end}")
    path.write_text("\n".join(out) + "\n", encoding="ascii")
    return path


def sigrok(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(["sigrok-cli", *args], capture_output=True, text=True, timeout=120,
                          env=env or dict(os.environ))
    return done


_ANN = re.compile(r"(\d+)-(\d+) ([\w-]+): (.*)")


@dataclass(frozen=True)
class Annotation:
    """One line of sigrok-cli's output: the sample span and the text (sigrok-cli 0.7 prints an
    annotation's first, longest text and no class)."""

    ss: int
    es: int
    text: str


def annotations(vcd: Path, env: dict[str, str], *decoders: str) -> list[Annotation]:
    """sigrok-cli's annotations of ``decoders`` stacked on the UART decoder over ``vcd``."""
    done = sigrok("-i", str(vcd), "-P", ",".join((UART, *decoders)), "-A", decoders[-1],
                  "--protocol-decoder-samplenum", env=env)
    assert done.returncode == 0 and not done.stderr, done.stderr
    out = []
    for line in done.stdout.splitlines():
        m = _ANN.fullmatch(line)
        assert m, f"not an annotation line: {line!r}"
        out.append(Annotation(int(m.group(1)), int(m.group(2)), m.group(4)))
    return out
