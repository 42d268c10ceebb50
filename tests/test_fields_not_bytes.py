"""The conformance checks of echoes and of the latched alarm compare fields, as the rulebook does
(docs/protocol.md "Behaviour the vendor text states": echoes judged by fields), and their docstrings and
the spec's comments say so: none says "byte for byte" (issue 23 item 12)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FILES = ["conformance/checks/test_echo.py", "conformance/checks/test_alarms.py", "xac1_proto/spec.py"]


@pytest.mark.parametrize("name", FILES)
def test_checks_that_compare_fields_never_say_byte_for_byte(name: str):
    """No comment or docstring of these files claims a byte-for-byte comparison."""
    text = (ROOT / name).read_text(encoding="utf-8").lower()
    assert "byte for byte" not in text and "byte-for-byte" not in text


def test_the_latched_alarm_check_compares_alarm_codes_not_bytes():
    """test_alarm_latched compares the alarm code of the answers, never their raw bytes."""
    tree = ast.parse((ROOT / "conformance/checks/test_alarms.py").read_text(encoding="utf-8"))
    compared = [ast.unparse(node) for node in ast.walk(tree) if isinstance(node, ast.Compare)]
    assert not [c for c in compared if ".raw" in c], compared
