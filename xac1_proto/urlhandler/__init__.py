"""pyserial URL handlers of this package; importing it registers them (``xac1sim://``).

pyserial looks up ``<package>.protocol_<scheme>`` for every package in
``serial.protocol_handler_packages``; ``xac1_proto/__init__.py`` imports this package so that
``serial.serial_for_url("xac1sim://...")`` works as soon as ``xac1_proto`` is imported.
"""

from __future__ import annotations

import serial

if __name__ not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(__name__)

registered = True
