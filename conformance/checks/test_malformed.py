"""Malformed commands of every kind are answered with an alarm answer, not silence.

docs/protocol.md "Framing" (wrong length, terminator, letter O, the 2, unknown header, field ranges) and
"Fields"; each probe ends with LF (silent item 1). Which alarm code comes back is information.
"""

from __future__ import annotations

import pytest

from conformance.kit import MALFORMED
from xac1_proto.codec import show_bytes
from xac1_proto.dut.evidence import describe_answer, expect

CASES = [pytest.param(m, id=m.name, marks=[pytest.mark.xac1_motion] if m.moves else []) for m in MALFORMED]


@pytest.mark.parametrize("bad", CASES)
def test_malformed_answered_with_alarm(xac1_dut, xac1_kit, bad):
    """A malformed command ({id}) gets an alarm answer, not silence and not a normal answer (docs/protocol.md
    "Framing"; "Behaviour the vendor text states")."""
    if bad.moves:
        xac1_kit.require_homed()
    p = xac1_dut.probe(bad.make(xac1_kit))
    expect(not p.timed_out, f"{bad.what} ({show_bytes(p.sent)}): expected an alarm answer 0%%Ec, received "
                            f"no answer (silence) within {xac1_dut.settings.timeout:g} s", p)
    expect(p.alarm is not None, f"{bad.what} ({show_bytes(p.sent)}): expected an alarm answer 0%%Ec, "
                                f"received {describe_answer(p)}", p)
