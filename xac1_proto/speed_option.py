"""The ``--speed-table`` option, defined once for every command that prices a move (``xac1 decode``,
``sniff``, ``proxy``; the simulator's table is the same ``motion.SpeedTable``).

How this works: ``add_speed_table_option(parser)`` adds the option, read by ``motion.SpeedTable.parse``
(``V:VEL:HOMING[:ACCEL]``); ``speeds_of(args)`` is the table to judge with: the one given, else the
guessed ``motion.DEFAULT_SPEEDS``, on which a move's answer window is only a reading (docs/protocol.md
silent items 15 and 17: a late answer is a notice; a table given makes the window firm).
"""

from __future__ import annotations

import argparse
from typing import Final

from . import motion

HELP: Final = ("the device's speed table as V:VEL:HOMING[:ACCEL]: pulses/s of speed number V 1, of direct "
               "speed vel 1 and of homing, and homing's acceleration number (default: our guess, "
               f"{motion.DEFAULT_SPEEDS.v_pps:g}:{motion.DEFAULT_SPEEDS.vel_pps:g}:"
               f"{motion.DEFAULT_SPEEDS.homing_pps:g}:{motion.DEFAULT_SPEEDS.homing_accel}, on which a late "
               "move answer is only a notice; a table given makes a move's window firm)")


def _speed_table(text: str) -> motion.SpeedTable:
    try:
        return motion.SpeedTable.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None  # argparse names the option


def add_speed_table_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--speed-table`` to ``parser``."""
    parser.add_argument("--speed-table", type=_speed_table, default=None, metavar="V:VEL:HOMING[:ACCEL]",
                        help=HELP)


def speeds_of(args: argparse.Namespace) -> motion.SpeedTable:
    """The speed table ``args`` give, else the guessed one."""
    table = getattr(args, "speed_table", None)
    return motion.DEFAULT_SPEEDS if table is None else table
