"""``xac1 parse`` and ``xac1 --version`` as a user runs them (a real subprocess)."""

from __future__ import annotations

import pytest
from conftest import xac1

import xac1_proto

pytestmark = pytest.mark.slow  # xac1 as a subprocess


def test_version():
    """``xac1 --version`` exits 0 and prints the package's version."""
    r = xac1("--version")
    assert r.returncode == 0 and xac1_proto.__version__ in r.stdout


def test_parse_vendor_answer_prints_fields():
    """``xac1 parse`` of the vendor's 0RP answer example prints its fields, the position in hex and
    decimal."""
    r = xac1("parse", r"0RP39302012345\r\n", "--role", "answer")
    assert r.returncode == 0, r.stderr
    assert "N=3 V=9 A=3 O=0 Pos=0x012345 (74565)" in r.stdout


def test_parse_letter_o_explains_and_exits_2():
    """A command sent with letter O for zero is named (``letter-o``), read as what it meant, and exits 2."""
    r = xac1("parse", r"ORP3\r\n", "--role", "command")
    assert r.returncode == 2
    assert "letter O" in r.stderr and "(letter-o)" in r.stderr
    assert "0RP command N=3" in r.stderr  # what it was read as
    assert r"'0RP3' CR LF" in r.stderr  # and the frame to send instead


def test_parse_hex_input_and_alarm_meaning():
    """``--hex`` input is read as bytes; an alarm answer is shown with its meaning from the alarm table."""
    r = xac1("parse", "30 25 25 30 45 0d 0a", "--hex", "--role", "answer")
    assert r.returncode == 0 and "emergency stop" in r.stdout


def test_parse_lists_every_deviation():
    """A frame with several faults lists each (``bad-length`` and ``missing-2``) and exits 2."""
    r = xac1("parse", r"0RS1\r\n", "--role", "answer")
    assert r.returncode == 2
    assert "(bad-length)" in r.stderr and "(missing-2)" in r.stderr


def test_parse_without_terminator_says_so():
    """A line with no LF is refused saying so (exit 2)."""
    r = xac1("parse", "0RV", "--role", "command")
    assert r.returncode == 2 and "no LF at the end" in r.stderr


def test_bad_hex_is_a_clear_error():
    """Text that is not hex bytes is bad input, not an invalid frame: a message and exit 1."""
    r = xac1("parse", "3Z", "--hex", "--role", "command")
    assert r.returncode == 1 and "--hex" in r.stderr and "Traceback" not in r.stderr
