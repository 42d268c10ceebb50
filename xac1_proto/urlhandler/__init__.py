"""pyserial URL handlers of this package; importing it registers them (``xac1sim://``).

pyserial looks up ``<package>.protocol_<scheme>`` for every package in
``serial.protocol_handler_packages``. Importing this package (``xac1_proto.client`` does) appends it
there, so that ``serial.serial_for_url("xac1sim://...")`` works; a script that uses pyserial alone can do
the same by hand: ``serial.protocol_handler_packages.append("xac1_proto.urlhandler")``. The sans-IO core
never imports this package: importing ``xac1_proto`` itself registers nothing.
"""

from __future__ import annotations

import serial

if __name__ not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(__name__)

registered = True
