"""The position table on disk (docs/protocol.md silent item 16): the simulator's non-volatile memory.

File format (JSON): ``{"format": "xac1sim-state", "version": 1, "points": {"1": {"v": 9, "a": 3,
"o": 0, "pos": 74565}, ...}}`` (only written points). ``save_state`` writes atomically
(``output_file.write_output``): a temporary file beside the file the path names (through a symbolic
link: the link stays), flushed and fsynced, renamed over the old one, then the directory fsynced; a
crash at any moment leaves the old or the new file, never a torn one. ``load_state`` raises
``StateFileError`` (what is wrong, where) for a file that is not ours or is corrupt; the caller must then
stop rather than overwrite it. A missing file is an empty table.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Final

from .. import spec
from ..errors import XAC1Error
from ..output_file import write_output
from .model import PointData

FORMAT: Final = "xac1sim-state"
VERSION: Final = 1


class StateFileError(XAC1Error):
    """A state file that cannot be used (corrupt, foreign or unreadable)."""


def _check_point(path: Path, key: str, raw: object) -> tuple[int, PointData]:
    where = f"{path}: point {key!r}"
    try:
        n = int(key, 16)
    except ValueError:
        raise StateFileError(f"{where}: expected a point number 1-F") from None
    lo, hi = spec.SPECS[("0WP", spec.COMMAND)].field_range("n")
    if not lo <= n <= hi:
        raise StateFileError(f"{where}: expected a point number 1-F")
    if not isinstance(raw, dict) or set(raw) != {"v", "a", "o", "pos"}:
        raise StateFileError(f"{where}: expected an object with v, a, o, pos; got {raw!r}")
    answer = spec.SPECS[("0RP", spec.ANSWER)]
    for name in ("v", "a", "o", "pos"):
        value = raw[name]
        lo, hi = answer.field_range(name)
        if not isinstance(value, int) or isinstance(value, bool) or not lo <= value <= hi:
            raise StateFileError(f"{where}: {name} must be an integer {lo}..{hi}, got {value!r}")
    return n, PointData(raw["v"], raw["a"], raw["o"], raw["pos"])


def load_state(path: str | os.PathLike[str]) -> dict[int, PointData]:
    """The position table stored in ``path`` ({} when the file does not exist)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    except (OSError, UnicodeDecodeError) as exc:
        raise StateFileError(f"{p}: cannot read the state file ({exc})") from None
    try:
        obj = json.loads(text)
    except ValueError as exc:
        raise StateFileError(f"{p}: not a simulator state file (not JSON: {exc}); "
                             f"it was left untouched") from None
    if not isinstance(obj, dict) or obj.get("format") != FORMAT:
        raise StateFileError(f"{p}: not a simulator state file (expected \"format\": \"{FORMAT}\"); "
                             f"it was left untouched")
    if obj.get("version") != VERSION:
        raise StateFileError(f"{p}: state file version {obj.get('version')!r}, expected {VERSION}")
    points = obj.get("points")
    if not isinstance(points, dict):
        raise StateFileError(f"{p}: \"points\" must be an object")
    return dict(_check_point(p, k, v) for k, v in points.items())


def dump_state(points: Mapping[int, PointData]) -> str:
    table = {f"{n:X}": {"v": d.v, "a": d.a, "o": d.o, "pos": d.pos} for n, d in sorted(points.items())}
    return json.dumps({"format": FORMAT, "version": VERSION, "points": table}, indent=1) + "\n"


def save_state(path: str | os.PathLike[str], points: Mapping[int, PointData]) -> None:
    """Write the table atomically and durably to the file ``path`` names (through a symbolic link, to
    its target: the link stays); see the module docstring. ``OutputFileError`` (a ``ValueError``) when
    ``path`` names something that is not a regular file, ``OSError`` when the write fails."""
    write_output(path, dump_state(points), durable=True)
