"""xac1-proto: protocol analyzer and conformance kit for the SUS XA-C1 actuator controller."""

from . import spec
from .client import Client
from .codec import diagnose, parse, show_bytes
from .errors import (
    AlarmError,
    CommunicationHalted,
    FrameError,
    ProtocolError,
    ResponseTimeout,
    Violation,
    XAC1Error,
)
from .exchange import Exchange
from .framer import FrameBytes, Framer, Junk
from .frames import *  # noqa: F403
from .frames import FRAME_CLASSES, Frame
from .urlhandler import registered as _xac1sim_url  # noqa: F401  (registers xac1sim://)

__version__ = "0.1.0"

__all__ = [
    "FRAME_CLASSES", "Frame", "FrameBytes", "FrameError", "Framer", "Junk", "Violation", "XAC1Error",
    "diagnose", "parse", "show_bytes", "spec",
    "AlarmError", "Client", "CommunicationHalted", "Exchange", "ProtocolError", "ResponseTimeout",
]
