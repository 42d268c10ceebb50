"""xac1-proto: protocol analyzer and conformance kit for the SUS XA-C1 actuator controller.

How this works: importing the package loads nothing but this file. Every public name below is taken
from its module on first use (PEP 562 ``__getattr__``), so ``import xac1_proto.framer`` (or spec,
grammar, frames, codec, motion, chunk: the sans-IO core) loads no serial port, socket, thread or clock,
and ``xac1_proto.Client`` still works. The ``xac1sim://`` URL handler registers itself when
``xac1_proto.client`` or ``xac1_proto.urlhandler`` is imported (docs/python-api.md).
"""

from __future__ import annotations

import importlib

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (``xac1`` starts faster)
if TYPE_CHECKING:
    from typing import Any

__version__ = "0.1.0"

# public name -> the module (relative to this package) that defines it
_LAZY: dict[str, str] = {
    "spec": ".spec",
    "Client": ".client",
    "diagnose": ".codec",
    "parse": ".codec",
    "show_bytes": ".codec",
    "AlarmError": ".errors",
    "CommunicationHalted": ".errors",
    "FrameError": ".errors",
    "ProtocolError": ".errors",
    "ResponseTimeout": ".errors",
    "Violation": ".errors",
    "XAC1Error": ".errors",
    "Exchange": ".exchange",
    "FrameBytes": ".framer",
    "Framer": ".framer",
    "Junk": ".framer",
    "Frame": ".frames",
    # the frame classes (frames.__all__), listed here so that naming one does not need frames loaded
    **dict.fromkeys((
        "FRAME_CLASSES", "ReadPoint", "WritePoint", "ReadCurrent", "StoreCurrent", "MovePoint",
        "MoveDirect", "ReadOutputs", "WriteOutputs", "ReadVersion", "SwitchMode", "AlarmReset",
        "PointAnswer", "ReadPointAnswer", "WritePointAnswer", "ReadCurrentAnswer", "StoreCurrentAnswer",
        "MovePointAnswer", "MoveDirectAnswer", "ReadOutputsAnswer", "WriteOutputsAnswer",
        "ReadVersionAnswer", "SwitchModeAnswer", "AlarmResetAnswer", "AlarmAnswer",
    ), ".frames"),
}

# spelled out (not ``[*_LAZY]``) so that linters see it; a test checks the two agree
__all__ = [
    "__version__", "spec", "Client", "diagnose", "parse", "show_bytes", "AlarmError", "CommunicationHalted",
    "FrameError", "ProtocolError", "ResponseTimeout", "Violation", "XAC1Error", "Exchange", "FrameBytes",
    "Framer", "Junk", "Frame", "FRAME_CLASSES", "ReadPoint", "WritePoint", "ReadCurrent", "StoreCurrent",
    "MovePoint", "MoveDirect", "ReadOutputs", "WriteOutputs", "ReadVersion", "SwitchMode", "AlarmReset",
    "PointAnswer", "ReadPointAnswer", "WritePointAnswer", "ReadCurrentAnswer", "StoreCurrentAnswer",
    "MovePointAnswer", "MoveDirectAnswer", "ReadOutputsAnswer", "WriteOutputsAnswer", "ReadVersionAnswer",
    "SwitchModeAnswer", "AlarmResetAnswer", "AlarmAnswer",
]


def __getattr__(name: str) -> Any:
    """Load a public name's module on first use (PEP 562) and cache the name here."""
    try:
        module_name = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    module = importlib.import_module(module_name, __name__)
    value = module if module_name == f".{name}" else getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


if TYPE_CHECKING:  # what the lazy names are, for type checkers and IDEs
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
    from .frames import (
        FRAME_CLASSES,
        AlarmAnswer,
        AlarmReset,
        AlarmResetAnswer,
        Frame,
        MoveDirect,
        MoveDirectAnswer,
        MovePoint,
        MovePointAnswer,
        PointAnswer,
        ReadCurrent,
        ReadCurrentAnswer,
        ReadOutputs,
        ReadOutputsAnswer,
        ReadPoint,
        ReadPointAnswer,
        ReadVersion,
        ReadVersionAnswer,
        StoreCurrent,
        StoreCurrentAnswer,
        SwitchMode,
        SwitchModeAnswer,
        WriteOutputs,
        WriteOutputsAnswer,
        WritePoint,
        WritePointAnswer,
    )
