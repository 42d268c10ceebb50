"""Recording a run: into its store, or into the local spool when the store cannot take it.

How this works: ``record(run, url)`` opens the store and adds the run. A store that cannot be reached,
or one of a newer schema, never changes the command's verdict or exit status: the run is spooled
(``spool.keep``) and one line on stderr says where and why; ``xac1 history sync`` sends it later.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from .model import RunRecord


@dataclass(frozen=True)
class Recorded:
    """Where a run went: its number in the store, or the spool file (then ``why``)."""

    url: str
    run_id: int | None = None
    spooled: Path | None = None
    why: str = ""


def record(run: RunRecord, url: str, program: str = "xac1") -> Recorded:
    """Record ``run`` in the store at ``url``; spool it (one warning line on stderr) when that fails."""
    from .spool import keep
    from .store import HistoryError, Store, shown

    try:
        with Store.open(url) as store:
            return Recorded(url, run_id=store.add(run))
    except HistoryError as exc:
        why = str(exc)
    try:
        path = keep(run, shown(url), why)
    except OSError as exc:
        print(f"{program}: history: {why}; and the spool could not keep the run either: "
              f"{exc.strerror or exc}; the run is not recorded", file=sys.stderr, flush=True)
        return Recorded(url, why=why)
    print(f"{program}: history: {why}; the run is kept in {path} (xac1 history sync sends it)",
          file=sys.stderr, flush=True)
    return Recorded(url, spooled=path, why=why)
