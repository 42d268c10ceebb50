"""The local spool: runs that could not reach their store, one JSON file each, until ``xac1 history
sync`` sends them.

How this works: ``keep(run, why)`` writes ``<spool>/<started>-<uid>.json`` atomically (a temporary file
beside it, then a rename), so a half-written file never passes for a run. ``sync(store)`` records every
spooled run in the store, oldest first, and removes each file only once its run is in (the store's
``uid`` check makes a run synced twice count once).
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from .model import RunRecord
from .where import spool_dir

if TYPE_CHECKING:
    from .store import Store


def keep(run: RunRecord, meant_for: str, why: str, folder: Path | None = None) -> Path:
    """Spool ``run`` (meant for the store ``meant_for``, password hidden; not reached because ``why``)."""
    folder = folder or spool_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{run.started.strftime('%Y%m%dT%H%M%S')}-{run.uid}.json"
    data = {"meant_for": meant_for, "why": why, "run": run.to_json()}
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=1)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def waiting(folder: Path | None = None) -> list[Path]:
    """The spooled runs, oldest first."""
    folder = folder or spool_dir()
    return sorted(folder.glob("*.json")) if folder.is_dir() else []


@dataclass
class Synced:
    """What a sync did: runs sent, files it could not read (kept, with the reason)."""

    sent: list[Path] = field(default_factory=list)
    unreadable: list[tuple[Path, str]] = field(default_factory=list)


def sync(store: Store, folder: Path | None = None) -> Synced:
    """Send every spooled run to ``store``; ``StoreUnreachable`` stops it (what was sent stays sent)."""
    done = Synced()
    for path in waiting(folder):
        try:
            run = RunRecord.from_json(json.loads(path.read_text(encoding="utf-8"))["run"])
        except (OSError, ValueError, KeyError, TypeError) as exc:
            done.unreadable.append((path, f"{type(exc).__name__}: {exc}"))
            continue
        store.add(run)
        path.unlink(missing_ok=True)
        done.sent.append(path)
    return done
