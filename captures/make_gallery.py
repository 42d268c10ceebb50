"""Make the capture gallery: one scripted XA-C1 session captured through every supported tool.

Run from the repository root: ``python captures/make_gallery.py [OUTDIR [NAME-PART]]`` (default:
``captures``, every file; NAME-PART remakes only the files whose name contains it).
Needs socat, jpnevulator, sigrok-cli and editcap (Debian packages socat, jpnevulator, sigrok-cli,
wireshark-common) and pyserial. The tests import this file to capture the same session live.

The session (``SESSION``) has a sloppy host (a letter O instead of the digit zero, a command sent
after an alarm without resetting it) and a faulty device (a wrong echo, a normal answer while the alarm
is latched, an answer ending in a bare LF, a command left unanswered). Real tools capture it live over
pseudo-terminals where they can (socat, jpnevulator, pyserial spy://); sigrok-cli decodes a UART
waveform synthesized from it; pcapng is written by ``sniffer.io.pcap.PcapngWriter`` and converted to
pcap by editcap; Saleae and interceptty files are written from their documented layouts.
"""

from __future__ import annotations

import contextlib
import csv
import os
import select
import subprocess
import sys
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

from sniffer.io.pcap import PcapngWriter
from xac1_proto.chunk import Chunk
from xac1_proto.recording import RecordingWriter

# (command the host sends, answer the device sends or None, pause after the step in seconds)
SESSION: list[tuple[bytes, bytes | None, float]] = [
    (b"0RV\r\n", b"0RV100\r\n", 0.15),
    (b"0RC\r\n", b"0RC00002FFFFFF\r\n", 0.15),
    (b"0WP19302012345\r\n", b"0WP19302012344\r\n", 0.15),  # faulty device: echo differs
    (b"ORP1\r\n", b"0%%01\r\n", 0.15),  # sloppy host: letter O; the device latches alarm 01
    (b"0RS\r\n", b"0RS02\r\n", 0.15),  # sloppy host: no reset; faulty device: answers while latched
    (b"0%C\r\n", b"0%C00\r\n", 0.15),
    (b"0RP1\r\n", b"0RP19302012345\n", 0.15),  # faulty device: bare LF
    (b"0RV\r\n", None, 1.4),  # faulty device: no answer
    (b"0RV\r\n", b"0RV100\r\n", 0.15),
]
EXPECTED_VIOLATIONS = ["echo-mismatch", "letter-o", "alarm-ignored", "latch-broken", "bad-terminator",
                       "bad-length", "no-answer"]
ANSWER_DELAY = 0.02  # seconds between a command's last byte and its answer
T0 = 1714557600.0  # synthesized captures start here (2024-05-01 10:00:00 UTC)
BAUD = 9600
BYTE_S = 10 / BAUD


def timeline(session: list[tuple[bytes, bytes | None, float]] = SESSION,
             t0: float = T0) -> Iterator[Chunk]:
    """The session as chunks with wire-accurate times (10 bits a byte at 9600 baud)."""
    t = t0
    for command, answer, pause in session:
        yield Chunk(t, "host", command)
        t += len(command) * BYTE_S + ANSWER_DELAY
        if answer is not None:
            yield Chunk(t, "device", answer)
            t += len(answer) * BYTE_S
        t += pause


def per_byte(chunks: Iterator[Chunk]) -> Iterator[Chunk]:
    for c in chunks:
        for k, b in enumerate(c.data):
            yield Chunk(c.t + k * BYTE_S, c.dir, bytes([b]), c.error)


# ---- live captures over ptys ----

def _raw_pty() -> tuple[int, int]:
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    return master, slave


def _drain(fd: int, n: int, timeout: float = 2.0) -> bytes:
    """Read n bytes from fd (fewer if the timeout passes)."""
    got = b""
    end = time.monotonic() + timeout
    while len(got) < n and time.monotonic() < end:
        r, _, _ = select.select([fd], [], [], max(0.0, end - time.monotonic()))
        if r:
            got += os.read(fd, n - len(got))
    return got


def play(host_write: Callable[[bytes], None], host_read: Callable[[int], bytes],
         dev_write: Callable[[bytes], None], dev_read: Callable[[int], bytes],
         session: list[tuple[bytes, bytes | None, float]] = SESSION, scale: float = 1.0) -> None:
    """Host and device take turns as the session says; each side reads what the other sent."""
    for command, answer, pause in session:
        host_write(command)
        dev_read(len(command))
        time.sleep(ANSWER_DELAY)
        if answer is not None:
            dev_write(answer)
            host_read(len(answer))
        time.sleep(pause * scale)


@contextlib.contextmanager
def _process(args: list[str], **kw: object) -> Iterator[subprocess.Popen]:
    p = subprocess.Popen(args, **kw)  # type: ignore[call-overload]
    try:
        yield p
    finally:
        p.terminate()
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def capture_socat(out: Path, options: list[str], session=SESSION, scale: float = 1.0) -> None:
    """``socat OPTIONS pty,link=HOST pty,link=DEVICE 2> out`` while the session plays."""
    links = out.parent / f".{out.name}.host", out.parent / f".{out.name}.dev"
    with open(out, "wb") as log, _process(["socat", *options, f"pty,link={links[0]},raw,echo=0",
                                           f"pty,link={links[1]},raw,echo=0"], stderr=log):
        end = time.monotonic() + 5
        while not all(p.exists() for p in links) and time.monotonic() < end:
            time.sleep(0.02)
        h = os.open(links[0], os.O_RDWR | os.O_NOCTTY)
        d = os.open(links[1], os.O_RDWR | os.O_NOCTTY)
        try:
            play(lambda b: os.write(h, b), lambda n: _drain(h, n), lambda b: os.write(d, b),
                 lambda n: _drain(d, n), session, scale)
            time.sleep(0.05)
        finally:
            os.close(h)
            os.close(d)


def _taken(slave: int, what: str, timeout: float = 10.0) -> bytes:
    """Wait until a reader has taken every byte waiting on the pty ``slave`` (its input queue, FIONREAD,
    is empty): the capture tool has read, and so timed, what was written, before anything else is."""
    end = time.monotonic() + timeout
    while _waiting(slave):
        if time.monotonic() > end:
            raise TimeoutError(f"jpnevulator did not read the {what} bytes within {timeout} s")
        time.sleep(0.001)
    return b""


def _waiting(fd: int) -> int:
    import fcntl
    import struct
    import termios

    return int(struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0])


def capture_jpnevulator(out: Path, options: list[str], names=("host", "device"), session=SESSION,
                        scale: float = 1.0) -> None:
    """``jpnevulator --read --timing-print --tty HOSTTTY:host --tty DEVTTY:device OPTIONS > out``:
    two ptys, one per line direction, as a sniffer cable with two receive lines gives. Each side writes
    only once jpnevulator has read what the other side wrote (the line's order is the capture's order
    however the machine schedules jpnevulator), and the session starts once it has opened both ttys."""
    (hm, hs), (dm, ds) = _raw_pty(), _raw_pty()
    ttys = [f"{os.ttyname(hs)}:{names[0]}" if names[0] else os.ttyname(hs),
            f"{os.ttyname(ds)}:{names[1]}" if names[1] else os.ttyname(ds)]
    try:
        args = ["jpnevulator", "--read", "--timing-print", "--tty", ttys[0], "--tty", ttys[1], *options]
        with open(out, "wb") as log, _process(args, stdout=log) as tool:
            _opened(tool.pid, [os.ttyname(hs), os.ttyname(ds)])
            play(lambda b: os.write(hm, b), lambda n: _taken(ds, "device"), lambda b: os.write(dm, b),
                 lambda n: _taken(hs, "host"), session, scale)
    finally:
        for fd in (hm, hs, dm, ds):
            os.close(fd)


def _opened(pid: int, paths: list[str], timeout: float = 10.0) -> None:
    """Wait until process ``pid`` holds every one of ``paths`` open (Linux /proc)."""
    end = time.monotonic() + timeout
    while True:
        held = set()
        with contextlib.suppress(OSError):
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                with contextlib.suppress(OSError):
                    held.add(os.readlink(fd))
        if set(paths) <= held:
            return
        if time.monotonic() > end:
            raise TimeoutError(f"jpnevulator did not open {', '.join(paths)} within {timeout} s")
        time.sleep(0.01)


def capture_spy(out: Path, session=SESSION, scale: float = 1.0) -> None:
    """The host program opens ``spy://PTY?file=out`` (pyserial) and talks to a device on the pty."""
    import serial

    master, slave = _raw_pty()
    port = serial.serial_for_url(f"spy://{os.ttyname(slave)}?file={out}", baudrate=BAUD, timeout=1)
    try:
        play(port.write, port.read, lambda b: os.write(master, b), lambda n: _drain(master, n),
             session, scale)
    finally:
        port.close()
        os.close(master)
        os.close(slave)


# ---- synthesized and hand-written captures ----

def uart_waveform(path: Path, samplerate: int, t0: float = T0) -> None:
    """Two channels (bit 0: host line, bit 1: device line), one byte a sample, idle high, 8N1."""
    spb = samplerate // BAUD
    events = []
    for c in per_byte(timeline(t0=t0)):
        start = round((c.t - t0) * samplerate) + spb * 10
        bits = [0] + [(c.data[0] >> i) & 1 for i in range(8)] + [1]
        events.append((start, 0 if c.dir == "host" else 1, bits))
    total = max(s for s, _, _ in events) + spb * 20
    with open(path, "wb") as f:
        levels = bytearray(b"\x03" * total)
        for start, channel, bits in events:
            for k, bit in enumerate(bits):
                lo, hi = start + k * spb, start + (k + 1) * spb
                mask = 1 << channel
                for s in range(lo, hi):
                    levels[s] = (levels[s] | mask) if bit else (levels[s] & ~mask)
        f.write(levels)


def capture_sigrok(out: Path, samplerate: int = 48000) -> list[str]:
    """sigrok-cli reads the synthesized waveform and prints the UART decoders' data annotations."""
    wave = out.parent / f".{out.name}.bin"
    uart_waveform(wave, samplerate)
    args = ["sigrok-cli", "-I", f"binary:numchannels=2:samplerate={samplerate}", "-i", str(wave),
            "-P", f"uart:rx=0:baudrate={BAUD}", "-P", f"uart:rx=1:baudrate={BAUD}", "-A", "uart=rx-data",
            "--protocol-decoder-samplenum"]
    with open(out, "wb") as f:
        subprocess.run(args, stdout=f, stderr=subprocess.DEVNULL, check=True, timeout=60)
    wave.unlink()
    return args


def write_pcapng(out: Path) -> None:
    with PcapngWriter(out) as w:
        for c in timeline():
            w.write(c)


def write_saleae_analyzer(host: Path, device: Path, radix: str = "hex", glitch: bool = False) -> None:
    """Logic 1.x analyzer export, one file per line, hex or ASCII radix. ``glitch``: the last digit of
    the device's faulty 0WP echo is flagged in the ``Framing Error`` column, as a noisy line shows."""
    with open(host, "w", newline="") as h, open(device, "w", newline="") as d:
        files = {"host": h, "device": d}
        for f in files.values():
            f.write("Time [s],Value,Parity Error,Framing Error\n")
        for c in per_byte(timeline(t0=0.0)):
            b = c.data[0]
            value = f"0x{b:02X}" if radix == "hex" else _saleae_ascii(b)
            framing = "Error" if glitch and c.t == _glitch_time() else ""
            files[c.dir].write(f"{c.t + 0.5:.9f},{value},,{framing}\n")


def _glitch_time() -> float:
    """Time (from 0) of the byte a framing error marks: the last digit of the device's 0WP echo."""
    for c in timeline(t0=0.0):
        if c.dir == "device" and c.data.startswith(b"0WP"):
            return c.t + (len(c.data) - 3) * BYTE_S
    raise AssertionError("the session has no 0WP answer")


def _saleae_ascii(b: int) -> str:
    """A byte as Logic 1.x shows it in ASCII radix: the character, escapes for CR/LF, names for the
    characters that would break the CSV."""
    return {0x0D: "\\r", 0x0A: "\\n", 0x2C: "COMMA", 0x20: "' '"}.get(b, chr(b))


def write_saleae_table(out: Path, glitch: bool = False) -> None:
    """Logic 2 data table export, both analyzers in one file (named host and device). ``glitch``: the
    byte of ``_glitch_time`` carries ``framing`` in the error column and a ``framing error`` row
    follows it."""
    with open(out, "w", newline="") as f:
        w = csv.writer(f, quoting=csv.QUOTE_MINIMAL, lineterminator="\n")
        w.writerow(["name", "type", "start_time", "duration", "data", "error"])
        for c in per_byte(timeline(t0=0.0)):
            bad = glitch and c.t == _glitch_time()
            w.writerow([c.dir, "data", f"{c.t + 0.5:.9f}", f"{BYTE_S:.9f}", f"0x{c.data[0]:02X}",
                        "framing" if bad else ""])
            if bad:
                w.writerow([c.dir, "framing error", f"{c.t + 0.5 + BYTE_S * 0.9:.9f}", "0", "", ""])


def write_interceptty(out: Path, timestamps: bool = False) -> None:
    """interceptty: ``<`` bytes the program on the front pty (the host) wrote, ``>`` (and a tab) bytes
    the device answered on the back port (interceptty's direction flags 0 and 1)."""
    with open(out, "w") as f:
        for c in timeline():
            stamp = time.strftime("[%H:%M %S", time.localtime(c.t)) + f".{round(c.t % 1 * 1e6):06d}]"
            for k, b in enumerate(c.data):
                prefix = (stamp if k == 0 else " " * len(stamp)) if timestamps else ""
                arrow = "< " if c.dir == "host" else "> \t"
                char = f" ({chr(b)})" if 33 <= b <= 126 else ""
                f.write(f"{prefix}{arrow}0x{b:02x}{char}\n")


def write_raw(host: Path, device: Path) -> None:
    with open(host, "wb") as h, open(device, "wb") as d:
        for c in timeline():
            (h if c.dir == "host" else d).write(c.data)


def write_recording(out: Path) -> None:
    with RecordingWriter(out, source="captures/make_gallery.py", started=T0) as w:
        for c in timeline():
            w.write(c)


def write_large_socat(out: Path, min_bytes: int) -> int:
    """A ``socat -x`` log of a faultless conversation repeated (times moving on) until it holds
    ``min_bytes``: for the progress-bar test and the memory benchmark, never kept in the gallery.
    Returns its size."""
    session = [*SESSION[:2], (b"0RP1\r\n", b"0RP19302012345\r\n", 0.15)]
    count = {">": 0, "<": 0}
    t = T0
    with open(out, "w") as f:
        while f.tell() < min_bytes:
            for c in timeline(session, t):
                side = ">" if c.dir == "host" else "<"
                clock = time.strftime("%Y/%m/%d %H:%M:%S", time.localtime(c.t))
                stamp = f"{clock}.{int(c.t % 1 * 1e6):06d}"
                f.write(f"{side} {stamp}  length={len(c.data)} from={count[side]} "
                        f"to={count[side] + len(c.data) - 1}\n {c.data.hex(' ')}\n")
                count[side] += len(c.data)
                t = c.t + 0.2
        return f.tell()


def main(outdir: str = "captures", only: str | None = None) -> int:
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    steps: list[tuple[str, Callable[[], object]]] = [
        ("socat-xv.log", lambda: capture_socat(out / "socat-xv.log", ["-x", "-v"])),
        ("socat-x.log", lambda: capture_socat(out / "socat-x.log", ["-x"])),
        ("socat-v.log", lambda: capture_socat(out / "socat-v.log", ["-v"])),
        ("jpnevulator.txt", lambda: capture_jpnevulator(out / "jpnevulator.txt", [])),
        ("jpnevulator-ascii.txt", lambda: capture_jpnevulator(
            out / "jpnevulator-ascii.txt", ["--ascii", "--byte-count", "--width", "8"], names=("", ""))),
        ("spy.log", lambda: capture_spy(out / "spy.log")),
        ("sigrok-uart.txt", lambda: capture_sigrok(out / "sigrok-uart.txt")),
        ("session.pcapng", lambda: write_pcapng(out / "session.pcapng")),
        ("session.pcap", lambda: subprocess.run(["editcap", "-F", "pcap", str(out / "session.pcapng"),
                                                 str(out / "session.pcap")], check=True, timeout=60)),
        ("saleae-host.csv", lambda: write_saleae_analyzer(out / "saleae-host.csv",
                                                          out / "saleae-device.csv")),
        ("saleae-ascii-host.csv", lambda: write_saleae_analyzer(
            out / "saleae-ascii-host.csv", out / "saleae-ascii-device.csv", radix="ascii", glitch=True)),
        ("saleae-logic2.csv", lambda: write_saleae_table(out / "saleae-logic2.csv")),
        ("saleae-logic2-glitch.csv", lambda: write_saleae_table(out / "saleae-logic2-glitch.csv",
                                                                glitch=True)),
        ("interceptty.log", lambda: write_interceptty(out / "interceptty.log")),
        ("interceptty-T.log", lambda: write_interceptty(out / "interceptty-T.log", timestamps=True)),
        ("raw-host.bin", lambda: write_raw(out / "raw-host.bin", out / "raw-device.bin")),
        ("recording.jsonl", lambda: write_recording(out / "recording.jsonl")),
    ]
    for name, make in steps:
        if only is not None and only not in name:
            continue
        print(f"making {name}", file=sys.stderr)
        make()
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
