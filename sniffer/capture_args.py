"""The capture options ``xac1 decode`` and ``xac1 replay`` share: the files, ``--input-format``,
``--host-is``, ``--samplerate``; each file opened once (``-`` is standard input), the format sniffed from
the buffered heads by ``sniffer.io.registry`` or taken from ``--input-format``, the other direction's
file found for formats that keep one direction a file.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Final

from xac1_proto import spec

from .io.base import Report, Source

INPUT_FORMATS: Final = ("auto", "jsonl", "pcap", "socat", "spy", "interceptty", "jpnevulator", "saleae",
                        "sigrok", "raw")
WRONG_FORMAT_LIMIT: Final = 10  # problems before any data, with --input-format: the format is wrong


def _rate(text: str) -> float:
    """``--samplerate``: a positive, finite rate in Hz."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a rate in Hz") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a sample rate in Hz above 0")
    return value


def add_capture_arguments(p: argparse.ArgumentParser) -> None:
    """The capture file(s) and how to read them."""
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="capture file(s) ('-' is standard input; pipes and FIFOs work); formats with one "
                        "file per direction take two")
    p.add_argument("--input-format", "-I", default="auto", choices=INPUT_FORMATS,
                   help="the capture's format (default: sniffed from the content)")
    p.add_argument("--host-is", metavar="SIDE", default=None,
                   help="which side is the host, named as the format names it: socat '>' or '<', spy TX/RX, "
                        "a jpnevulator alias or tty, a sigrok instance (uart-1) or class (tx-data), a Saleae "
                        "file or analyzer name, a raw file, pcap TX/RX")
    p.add_argument("--samplerate", type=_rate, metavar="HZ", default=None,
                   help="sigrok: sample rate turning sample numbers (--protocol-decoder-samplenum) into "
                        f"time (default: inferred from the byte lengths at {spec.BAUD} baud)")


def open_sources(files: list[str], report: Report) -> list[Source]:
    """Each file opened once (``-``: standard input); a missing file or a directory is a FormatError."""
    from pathlib import Path

    from .io.base import STDIN, FormatError

    if files.count(STDIN) > 1:
        raise FormatError("'-' (standard input) can be given once")
    sources: list[Source] = []
    try:
        for f in files:
            if f != STDIN:
                path = Path(f)
                if not path.exists():
                    raise FormatError(f"{f}: no such file")
                if path.is_dir():
                    raise FormatError(f"{f}: is a directory; give the capture file(s) in it")
            sources.append(Source(f, report))
    except BaseException:
        for src in sources:
            src.close()
        raise
    return sources


def choose_format(sources: list[Source], args: argparse.Namespace, report: Report,
                  program: str) -> tuple[str, bool]:
    """The input format (sniffed, or ``--input-format``); a found partner file is appended to
    ``sources``. Also says whether the capture holds one line direction only (half of a capture that
    keeps one direction a file, the other file missing)."""
    from .io import saleae
    from .io.registry import SURE, detect, sniff_one

    fmt = args.input_format
    if fmt == "auto":
        found = detect(sources)
        fmt = found.name
        close = [(n, s) for n, s in found.considered[1:] if s >= SURE]
        if close:
            others = ", ".join(f"{n} ({s})" for n, s in close)
            print(f"{program}: reading as {fmt} (also considered: {others})", file=sys.stderr)
    else:
        looks = [(src.name, sniff_one(src)) for src in sources]
        report.give_up_after = WRONG_FORMAT_LIMIT
        report.looks_like = ", ".join(f"{name} looks like a {seen} capture" for name, seen in looks
                                      if seen not in (None, fmt))
    one_file_per_side = fmt == "raw" or (fmt == "saleae" and all(
        saleae.one_direction(src.head()) for src in sources))
    if len(sources) == 1 and one_file_per_side:
        partner = _partner(sources[0].name) if sources[0].regular else None
        if partner is None:
            report.note(f"{sources[0].name} holds one line direction only ({fmt} keeps one a file) and "
                        f"no file of the other direction was given or found: the other direction is "
                        f"missing, so nothing that needs both (answers, pairing, no-answer, alarms) is "
                        f"judged; give both files")
            return fmt, True
        print(f"{program}: {fmt} keeps one line direction a file: reading {partner} with it",
              file=sys.stderr)
        sources.append(Source(partner, report))
    return fmt, False


def _partner(path: str) -> str | None:
    """The other direction's file of a one-file-per-direction capture: ``host`` <-> ``device`` in the
    name (``saleae-host.csv`` -> ``saleae-device.csv``), when that file exists."""
    import os
    import re

    folder, name = os.path.split(path)
    swap = {"host": "device", "device": "host", "Host": "Device", "Device": "Host", "HOST": "DEVICE",
            "DEVICE": "HOST"}
    other, n = re.subn(r"host|device", lambda m: swap.get(m.group(0), m.group(0)), name, count=1,
                       flags=re.IGNORECASE)
    candidate = os.path.join(folder, other)
    return candidate if n and candidate != path and os.path.isfile(candidate) else None
