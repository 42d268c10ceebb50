"""``xac1 decode --batch DIR|GLOB... [--jobs N]``: an archive of captures, one conversation per file.

How this works: each argument is a directory (its files, not recursive, hidden ones left out), a file, or
a glob pattern (what is not a regular file, a FIFO or a device, is left out and named on stderr); the
files are decoded each on its own (exactly ``xac1 decode FILE``: the same format
detection, options and summary), one process per file, at most ``--jobs`` at a time (default: the cores
this process may run on), the largest files first, so an archive goes about as many times faster as there
are cores. Printed in
the order given: one row per file and a total (``--format jsonl``: a ``{"type":"file",...}`` line per file
holding that file's summary record and exit status, then ``{"type":"total",...}``). Exit status: 2 when
a file decoded nothing (missing, unknown format, no line data), else 1 when any file has violations or
problems, else 0. A file on which decoding raises (a bug) is one row with exit 2 and the error on
stderr: the other files keep their rows.
"""

from __future__ import annotations

import argparse
import contextlib
import glob
import io
import json
import os
import stat
import sys
import traceback
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from .io.base import shown

_MESSAGES = "_stderr"  # a row's key for what decoding the file said on stderr (taken out before printing)
_REFUSED = ("report", "annotate", "only_violations", "header")  # per-record options: not in a batch


def default_jobs() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def kind_of(path: Path) -> str:
    """What a path that is not a regular file is, in words (for the message naming it)."""
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    for test, what in ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISDIR, "a directory")):
        if test(mode):
            return what
    return "not a regular file"


def expand(specs: list[str]) -> tuple[list[str], list[str], list[str]]:
    """(the files, in the order given without repeats; what was wrong with an argument: one that matched
    nothing, or names no regular file (each makes the batch exit 2); what was left out from a directory
    or a pattern that is not a regular file: a FIFO, a device, a socket, which a batch does not read,
    each named with why). Subdirectories of a directory are not entered, silently."""
    files: dict[str, None] = {}
    wrong: list[str] = []
    skipped: list[str] = []

    def regular(p: Path, into: list[str]) -> bool:
        if p.is_file():
            return True
        if into is wrong or not p.is_dir():
            into.append(f"{p}: skipped: {kind_of(p)}, not a regular file (a batch reads files only; "
                        f"decode it on its own: xac1 decode {p})")
        return False

    for spec in specs:
        path = Path(spec)
        if path.is_dir():
            found = sorted(str(p) for p in path.iterdir()
                           if not p.name.startswith(".") and regular(p, skipped))
        elif path.exists():
            found = [spec] if regular(path, wrong) else []
            if not found:
                continue
        else:
            found = sorted(p for p in glob.glob(spec) if regular(Path(p), skipped))
        if not found:
            wrong.append(f"{spec}: no file matches (a directory, a file or a glob pattern)")
        files.update(dict.fromkeys(found))
    return list(files), wrong, skipped


Decode = Callable[[argparse.Namespace, list[dict[str, Any]]], int]


def decode_one(path: str, args: argparse.Namespace, decode: Decode) -> dict[str, Any]:
    """The row of one file: its summary record (as ``xac1 decode FILE --format jsonl`` ends) and exit.
    ``decode``: one file's decode (``decode_cli.run``, handed in: this module sits below the CLI)."""
    one = argparse.Namespace(**vars(args))
    one.files, one.batch, one.format, one.color = [path], False, "summary", False
    summaries: list[dict[str, Any]] = []
    messages = io.StringIO()  # kept with the row: printed in file order, never interleaved
    with contextlib.redirect_stderr(messages):
        try:
            status = decode(one, summaries)
        except Exception as exc:  # a bug met on this file: its row says so, the other files go on
            status = 2
            traceback.print_exc(file=messages)
            print(f"xac1 decode: {path}: internal error ({type(exc).__name__}: {shown(str(exc), 200)}), "
                  f"this file's row is incomplete; please report it with the file", file=messages)
    row: dict[str, Any] = {"type": "file", "file": path, "exit": status}
    if summaries:
        row.update((k, v) for k, v in summaries[0].items() if k != "type")
    row[_MESSAGES] = messages.getvalue()
    return row


def total(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The counts of every file added up (latencies are per file only)."""
    out: dict[str, Any] = {"type": "total", "files": len(rows),
                           "failed": sum(1 for r in rows if r["exit"] == 2)}
    for key in ("frames", "bytes"):
        out[key] = {side: sum(r.get(key, {}).get(side, 0) for r in rows) for side in ("host", "device")}
    violations: Counter[str] = Counter()
    for r in rows:
        violations.update(r.get("violations", {}))
    out["junk"] = sum(r.get("junk", 0) for r in rows)
    out["violations"] = dict(violations)
    out["problems"] = sum(r.get("problems", 0) for r in rows)
    out["line_errors"] = sum(r.get("line_errors", 0) for r in rows)
    out["unanswered"] = sum(r.get("unanswered", 0) for r in rows)
    return out


def _row_text(name: str, fmt: str, r: dict[str, Any], exit_text: str) -> str:
    frames, violations = r.get("frames", {}), sum(r.get("violations", {}).values())
    return (f"{name:<40} {fmt:<12} {frames.get('host', 0):>10} {frames.get('device', 0):>10} "
            f"{r.get('junk', 0):>7} {violations:>10} {r.get('problems', 0):>8} {exit_text:>4}")


def _size(path: str) -> int:
    try:
        return os.path.getsize(path)
    except OSError:  # gone or unreadable: decoding it says so
        return 0


def decode_all(files: list[str], args: argparse.Namespace, decode: Decode, jobs: int) -> list[dict[str, Any]]:
    """The rows of ``files``, in the order given: in this process for one job or one file, else a process
    each up to ``jobs``, the largest first (the processes then end about together)."""
    if jobs == 1 or len(files) == 1:
        return [decode_one(f, args, decode) for f in files]
    with ProcessPoolExecutor(max_workers=min(jobs, len(files))) as pool:
        futures = {k: pool.submit(decode_one, files[k], args, decode)
                   for k in sorted(range(len(files)), key=lambda k: -_size(files[k]))}
        return [futures[k].result() for k in range(len(files))]


def print_rows(rows: list[dict[str, Any]], fmt: str) -> None:
    """The rows and their total on stdout: JSON lines (``--format jsonl``), else a table."""
    all_rows = rows + [total(rows)]
    if fmt == "jsonl":
        for row in all_rows:
            print(json.dumps(row, separators=(",", ":")))
    else:
        print(f"{'file':<40} {'format':<12} {'host':>10} {'device':>10} {'junk':>7} {'violations':>10} "
              f"{'problems':>8} {'exit':>4}")
        for r in rows:
            print(_row_text(r["file"], r.get("format", "-"), r, str(r["exit"])))
        t = all_rows[-1]
        print(_row_text(f"total ({t['files']} files, {t['failed']} failed)", "", t, ""))
    sys.stdout.flush()


def batch_status(rows: list[dict[str, Any]], wrong: list[str]) -> int:
    """2 when an argument was wrong or a file decoded nothing, else 1 when any file has violations or
    problems, else 0 (module docstring)."""
    if wrong or any(r["exit"] == 2 for r in rows):
        return 2
    return 1 if any(r["exit"] for r in rows) else 0


def run(args: argparse.Namespace, decode: Decode) -> int:
    """``xac1 decode --batch``: every file decoded by ``decode``, a process each up to ``--jobs``."""
    refused = [f"--{name.replace('_', '-')}" for name in _REFUSED if getattr(args, name, None)]
    if refused:
        print(f"xac1 decode: --batch prints one summary row per file; {', '.join(refused)} "
              f"work on one capture only", file=sys.stderr)
        return 2
    files, wrong, skipped = expand(args.files)
    for message in wrong + skipped:
        print(f"xac1 decode: {message}", file=sys.stderr)
    if not files:
        return 2
    rows = decode_all(files, args, decode, args.jobs or default_jobs())
    for row in rows:
        sys.stderr.write(row.pop(_MESSAGES))
    print_rows(rows, args.format)
    return batch_status(rows, wrong)
