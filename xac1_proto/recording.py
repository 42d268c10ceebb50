"""Our own recording format: JSON lines of raw chunks, written so that a crash loses nothing.

Line 1: ``{"type":"recording","version":1,"started":<unix s>,"source":"<free text>"}``; then one line
per chunk as it was seen: ``{"type":"chunk","t":<unix s or null>,"dir":"host"|"device","data":"<hex>"}``
(``"error":"..."`` when the source flagged the bytes). A program may add remarks between them:
``{"type":"note","t":<unix s>,"text":"..."}`` (``xac1 sim --replay``: a line not in the capture); readers
skip them. Each line is written and flushed to the OS as
soon as the chunk is seen, so a process killed with kill -9 keeps every line written; the file is
fsynced at least once a second (and on close) against power loss, when it is a regular file: a FIFO
or ``/dev/null`` is written without syncing. The file is opened by ``output_file.open_stream``: never a
FIFO nobody reads, never an existing file that is not a recording. A chunk longer than
``DATA_PER_LINE`` bytes is written as several chunk lines of the same time, so every line stays well
inside ``LONGEST_LINE``, the longest line a reader takes.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any, Final, Protocol

from .chunk import Chunk
from .output_file import can_sync, close_stream, open_stream

VERSION = 1
FSYNC_EVERY_S = 1.0
LONGEST_LINE: Final = 1 << 20  # characters: a longer line is one problem, never read
DATA_PER_LINE: Final = 1 << 18  # bytes of a chunk a line holds (as hex, half of LONGEST_LINE)


class RecordingWriter:
    """Append chunks to a recording file; a context manager that flushes and closes."""

    def __init__(self, path: str | os.PathLike[str], source: str = "",
                 started: float | None = None) -> None:
        self.path = Path(path)
        self._f: IO[str] = open_stream(path, "w", encoding="ascii", buffering=1)
        self._syncable = can_sync(self._f)
        self._last_sync = time.monotonic()
        self._write({"type": "recording", "version": VERSION,
                     "started": time.time() if started is None else started, "source": source})

    def _write(self, obj: dict[str, Any]) -> None:
        self._f.write(json.dumps(obj, separators=(",", ":")) + "\n")
        self._f.flush()
        now = time.monotonic()
        if self._syncable and now - self._last_sync >= FSYNC_EVERY_S:
            os.fsync(self._f.fileno())
            self._last_sync = now

    def write(self, chunk: Chunk) -> None:
        data = chunk.data
        for at in range(0, max(len(data), 1), DATA_PER_LINE):
            obj: dict[str, Any] = {"type": "chunk", "t": chunk.t, "dir": chunk.dir,
                                   "data": data[at:at + DATA_PER_LINE].hex()}
            if chunk.error:
                obj["error"] = chunk.error
            self._write(obj)

    def note(self, text: str, t: float | None = None) -> None:
        """A remark in the recording at time ``t`` (default: now); readers skip it."""
        self._write({"type": "note", "t": time.time() if t is None else t, "text": text})

    def close(self) -> None:
        close_stream(self._f)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def is_recording(first_line: str) -> bool:
    """Content sniffing: does this first line start one of our recordings?"""
    try:
        obj = json.loads(first_line)
    except ValueError:
        return False
    return isinstance(obj, dict) and obj.get("type") == "recording"


def load_line(text: str) -> Any:
    """One JSON line as an object; ValueError in our words where ``json`` would pass on Python's own
    (a number of more digits than ``int`` converts: ``sys.get_int_max_str_digits``)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        raise
    except ValueError:
        raise ValueError("a number with more digits than any field has") from None


def chunk_of(text: str) -> Chunk | None:
    """The chunk one recording line holds; None for the header line and notes. ValueError, KeyError,
    TypeError or AttributeError when the line is malformed."""
    obj = load_line(text)
    if obj.get("type") in ("recording", "note"):
        return None
    if obj.get("type") != "chunk" or obj.get("dir") not in ("host", "device"):
        raise ValueError("not a chunk line")
    return Chunk(obj["t"], obj["dir"], bytes.fromhex(obj["data"]), obj.get("error"))


def read_recording(lines: Iterator[str], name: str = "<recording>",
                   problems: list[str] | None = None) -> Iterator[Chunk]:
    """Chunks of a recording; a malformed line is noted in ``problems`` (file and line) and skipped."""
    for number, line in enumerate(lines, 1):
        line = line.strip()
        if not line:
            continue
        try:
            chunk = chunk_of(line)
            if chunk is not None:
                yield chunk
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            if problems is None:
                raise ValueError(f"{name}:{number}: {exc}") from None
            problems.append(f"{name}:{number}: malformed recording line ({exc})")


class ChunkWriter(Protocol):
    """What a shell records to: one chunk at a time, then close."""

    def write(self, chunk: Chunk) -> None: ...

    def close(self) -> None: ...


RECORDERS_GROUP = "xac1_proto.recorders"  # entry points: file suffix (no dot) -> opener


def open_recording(path: str | os.PathLike[str], source: str = "", *, analyze: bool = False) -> ChunkWriter:
    """A recording for ``path`` chosen by its suffix: a format registered under the entry-point group
    ``xac1_proto.recorders`` (the sniffer registers ``pcapng``: Wireshark files with our verdicts as
    packet comments; ``analyze``: the caller has no analyzer of its own, so the recorder runs one), else
    our JSON lines recording. The core names no recorder above it; installed packages plug theirs in,
    as pyserial's URL handlers do. Raises OSError when the file cannot be written."""
    from importlib.metadata import entry_points

    suffix = Path(path).suffix.lower().lstrip(".")
    for entry in entry_points(group=RECORDERS_GROUP):
        if entry.name == suffix:
            opener = entry.load()
            writer: ChunkWriter = opener(path, source, analyze=analyze)
            return writer
    return RecordingWriter(path, source=source)
