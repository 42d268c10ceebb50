"""``xac1 ports``: the serial ports on this machine, and (``--probe``) which of them answer as an XA-C1.

How it works: pyserial's ``serial.tools.list_ports.comports()`` enumerates the ports (on Linux from
sysfs: USB vendor:product, serial number, location, description); a port that has a stable name under
``/dev/serial/by-id/`` is shown by it, since ``/dev/ttyUSB3`` changes with the order adapters are
plugged in. pseudo-terminals and ``socket://`` URLs are not enumerated: ``--port URL`` adds them.
``--probe`` opens each port exclusively (pyserial's ``exclusive=True``: a lock another program holding
the port with the same lock makes us skip it, saying so), sends one ``0RV`` at 9600 8N1 through
``Client`` (a read: it changes nothing on the controller, docs/protocol.md "Frames", 0RV) and reports
the firmware of those that answer as an XA-C1. Ports are probed in parallel, each with a short timeout.
Any ``hwgrep://REGEX`` URL pyserial accepts (e.g. ``hwgrep://SER=A1B2C3``) names a port by what this
command lists, wherever a port is taken.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

HELP = "list the serial ports (USB ids, serial numbers) and, with --probe, which answer as an XA-C1"

BY_ID_DIR = Path("/dev/serial/by-id")  # udev's stable names: one symlink a USB serial interface
PROBE_TIMEOUT_S = 0.5  # an XA-C1 answers 0RV within milliseconds; the wait is per port, ports in parallel


@dataclass
class Probe:
    """What ``0RV`` found on one port. ``result``: ``xac1`` (answered as an XA-C1), ``no-answer``,
    ``not-xac1`` (bytes came back that are no XA-C1 answer), ``busy`` (another program holds the port;
    nothing sent), ``error`` (could not open or write)."""

    result: str
    firmware: str | None = None  # the three digits 0RV answered, e.g. "100"
    detail: str = ""


@dataclass
class PortRow:
    """One port as listed: ``port`` is the name to use (the by-id path when there is one)."""

    port: str
    device: str
    by_id: str | None = None
    usb: str | None = None  # "VID:PID" in hex
    serial_number: str | None = None
    location: str | None = None
    description: str | None = None
    manufacturer: str | None = None
    product: str | None = None
    hwid: str | None = None
    listed: bool = True  # False: given with --port, not enumerated
    probe: Probe | None = field(default=None)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--probe", action="store_true",
                   help="send 0RV (read-only) at 9600 8N1 to each port no other program holds and show which "
                        "answer as an XA-C1, and their firmware")
    p.add_argument("--port", action="append", default=[], metavar="URL",
                   help="also list (and probe) this port: a pty path or a pyserial URL such as "
                        "socket://HOST:PORT (list_ports does not enumerate those); repeatable")
    p.add_argument("--format", choices=("text", "jsonl"), default="text",
                   help="text (a table, default) or jsonl (one JSON object a port)")
    p.add_argument("--timeout", type=float, default=PROBE_TIMEOUT_S, metavar="S",
                   help=f"with --probe: seconds to wait for each answer (default {PROBE_TIMEOUT_S})")


def stable_names(by_id_dir: Path | None = None) -> dict[str, str]:
    """Device path -> its ``/dev/serial/by-id/...`` symlink ({} when the directory does not exist)."""
    try:
        links = sorted((by_id_dir or BY_ID_DIR).iterdir())
    except OSError:
        return {}
    return {os.path.realpath(link): str(link) for link in links}


def enumerate_ports(by_id_dir: Path | None = None) -> list[PortRow]:
    """The ports pyserial's ``list_ports`` finds, each with its stable name when udev made one."""
    from serial.tools import list_ports

    stable = stable_names(by_id_dir)
    rows = []
    for info in sorted(list_ports.comports(), key=lambda i: i.device):
        by_id = stable.get(os.path.realpath(info.device))
        usb = f"{info.vid:04X}:{info.pid:04X}" if info.vid is not None and info.pid is not None else None
        rows.append(PortRow(port=by_id or info.device, device=info.device, by_id=by_id, usb=usb,
                            serial_number=info.serial_number, location=info.location,
                            description=_known(info.description), manufacturer=info.manufacturer,
                            product=info.product, hwid=_known(info.hwid)))
    return rows


def _known(text: str | None) -> str | None:
    return None if text in (None, "", "n/a") else text


def extra_rows(urls: Iterable[str], listed: Sequence[PortRow]) -> list[PortRow]:
    """Rows for ``--port`` URLs not already listed (a by-id path or device of a listed port is that port)."""
    known = {os.path.realpath(r.device) for r in listed}
    out = []
    for url in urls:
        if "://" not in url and os.path.realpath(url) in known:
            continue
        out.append(PortRow(port=url, device=url, listed=False))
    return out


def probe(url: str, timeout: float) -> Probe:
    """Open ``url`` exclusively, send one 0RV, and say what came back."""
    import serial

    from ..client import Client
    from ..codec import show_bytes
    from ..errors import ResponseTimeout, XAC1Error
    from ..frames import AlarmAnswer, ReadVersion, ReadVersionAnswer

    try:
        port = serial.serial_for_url(url, do_not_open=True, exclusive=True)
        port.open()
    except serial.SerialException as exc:
        if "exclusively lock" in str(exc) or getattr(exc, "errno", None) in (11, 16):  # EAGAIN, EBUSY
            return Probe("busy", detail="another program holds this port; not probed")
        return Probe("error", detail=f"cannot open: {exc}")
    except (OSError, ValueError) as exc:
        return Probe("error", detail=f"cannot open: {exc}")
    try:
        with Client(port, timeout=timeout, storm_limit=None) as client:
            exchange = client.transact(ReadVersion().to_bytes())
    except ResponseTimeout:
        return Probe("no-answer", detail=f"no answer to 0RV within {timeout:g} s")
    except (serial.SerialException, OSError, XAC1Error) as exc:
        return Probe("error", detail=f"port error: {exc}")
    finally:
        port.close()
    frame = exchange.frame
    if isinstance(frame, ReadVersionAnswer) and not exchange.errors:
        v = frame.version
        return Probe("xac1", firmware=v, detail=f"XA-C1, firmware {v} (version {v[:1]}.{v[1:]})")
    if isinstance(frame, AlarmAnswer) and not exchange.errors:
        return Probe("xac1", detail=f"XA-C1 with alarm {frame.code:02X} latched ({frame.meaning}); "
                                    f"firmware not read")
    return Probe("not-xac1", detail=f"answered {show_bytes(exchange.raw)}, not as an XA-C1")


def probe_all(rows: Sequence[PortRow], timeout: float) -> None:
    """Probe every row in parallel (each port has its own wait)."""
    if not rows:
        return
    with ThreadPoolExecutor(max_workers=min(16, len(rows))) as pool:
        for row, result in zip(rows, pool.map(lambda r: probe(r.port, timeout), rows), strict=True):
            row.probe = result


COLUMNS = (("PORT", "port"), ("DEVICE", "device"), ("USB", "usb"), ("SERIAL", "serial_number"),
           ("LOCATION", "location"), ("DESCRIPTION", "description"))


def text_lines(rows: Sequence[PortRow], probed: bool) -> list[str]:
    """An aligned table, nothing cut; ``-`` where a port has no such property."""
    heads = [h for h, _ in COLUMNS] + (["PROBE (0RV)"] if probed else [])
    table = []
    for r in rows:
        cells = [getattr(r, name) or "-" for _, name in COLUMNS]
        if r.device == r.port:
            cells[1] = "" if r.listed else "(given)"
        if probed:
            cells.append(r.probe.detail if r.probe else "-")
        table.append(cells)
    widths = [max(len(h), *(len(c[i]) for c in table)) if table else len(h) for i, h in enumerate(heads)]
    fmt = lambda cells: "  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip()
    return [fmt(heads), *(fmt(c) for c in table)]


def json_record(row: PortRow) -> dict[str, Any]:
    return asdict(row)


def run(args: argparse.Namespace) -> int:
    if args.timeout <= 0:
        print("xac1 ports: --timeout must be > 0", file=sys.stderr)
        return 2
    rows = enumerate_ports()
    rows += extra_rows(args.port, rows)
    if args.probe:
        probe_all(rows, args.timeout)
    if args.format == "jsonl":
        for row in rows:
            print(json.dumps(json_record(row)))
        return 0
    if not rows:
        print("no serial ports found (ptys and socket:// URLs are not enumerated: add them with --port)")
        return 0
    print("\n".join(text_lines(rows, args.probe)))
    if args.probe:
        found = sum(1 for r in rows if r.probe and r.probe.result == "xac1")
        print(f"{found} of {len(rows)} port(s) answered as an XA-C1")
    return 0
