"""The XA-C1 device simulator: a sans-IO model (``model``) and thin shells (pty, TCP, ``xac1sim://``).

Quick use::

    from xac1_proto.sim import DeviceModel, SimConfig, serve_pty, serve_tcp
    with serve_pty(SimConfig(time_scale=0)) as sim:      # sim.path, sim.url, sim.model
        ...  # serial.Serial(sim.path, 9600)
    with serve_tcp(SimConfig(time_scale=0)) as sim:      # sim.port, sim.url == "socket://127.0.0.1:PORT"
        ...
    serial.serial_for_url("xac1sim://?time_scale=0&deviation=no-2")   # in-process, no thread

Importing this package or ``xac1_proto.sim.model`` loads no I/O: the shells (``serve_pty``,
``serve_tcp``, ``RunningSim``) load on first use, and ``xac1sim://`` is registered where a URL is
opened (``xac1_proto.client``, ``xac1_proto.urlhandler``), not here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .config import DEVIATIONS, OPTIONS, LineFaults, SimConfig, config_from_options
from .model import DeviceModel, PointData
from .outbox import Outbox, Output

if TYPE_CHECKING:
    from .runner import RunningSim, serve_pty, serve_tcp

_SHELLS = frozenset({"RunningSim", "serve_pty", "serve_tcp"})

__all__ = [
    "DEVIATIONS", "OPTIONS", "DeviceModel", "LineFaults", "Outbox", "Output", "PointData", "RunningSim",
    "SimConfig", "config_from_options", "serve_pty", "serve_tcp",
]


def __getattr__(name: str) -> Any:
    """The shells load on first use (PEP 562), so the model is importable without ports or threads."""
    if name in _SHELLS:
        from . import runner

        return getattr(runner, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
