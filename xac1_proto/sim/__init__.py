"""The XA-C1 device simulator: a sans-IO model (``model``) and thin shells (pty, TCP, ``xac1sim://``).

Quick use::

    from xac1_proto.sim import DeviceModel, SimConfig, serve_pty, serve_tcp
    with serve_pty(SimConfig(time_scale=0)) as sim:      # sim.path, sim.url, sim.model
        ...  # serial.Serial(sim.path, 9600)
    with serve_tcp(SimConfig(time_scale=0)) as sim:      # sim.port, sim.url == "socket://127.0.0.1:PORT"
        ...
    serial.serial_for_url("xac1sim://?time_scale=0&deviation=no-2")   # in-process, no thread
"""

from .. import urlhandler as _urlhandler  # noqa: F401  (registers xac1sim://)
from .config import DEVIATIONS, OPTIONS, LineFaults, SimConfig, config_from_options
from .model import DeviceModel, PointData
from .outbox import Outbox, Output
from .runner import RunningSim, serve_pty, serve_tcp

__all__ = [
    "DEVIATIONS", "OPTIONS", "DeviceModel", "LineFaults", "Outbox", "Output", "PointData", "RunningSim",
    "SimConfig", "config_from_options", "serve_pty", "serve_tcp",
]
