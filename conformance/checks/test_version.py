"""0RV: the firmware version, three decimal digits."""

from __future__ import annotations

from xac1_proto.dut.evidence import describe_answer, expect
from xac1_proto.frames import ReadVersion, ReadVersionAnswer


def test_version_format(xac1_dut):
    """0RV answers 0RV and three decimal digits (docs/protocol.md "Frames", 0RV; "Fields", ver)."""
    p = xac1_dut.send(ReadVersion())
    bad = [v for v in p.violations if v.code == "field-range"]
    expect(isinstance(p.frame, ReadVersionAnswer) and not bad,
           f"0RV got {describe_answer(p)}" + (f": {bad[0]}" if bad else ""), p)
    v = p.frame.version
    xac1_dut.info("firmware version", "Frames (0RV)", f"{v} (version {int(v) // 100}.{int(v) % 100:02d})", p)


def test_version_stable(xac1_dut):
    """0RV answers the same version every time (docs/protocol.md "Frames", 0RV: the firmware version)."""
    a, b = xac1_dut.send(ReadVersion()), xac1_dut.send(ReadVersion())
    expect(isinstance(a.frame, ReadVersionAnswer) and isinstance(b.frame, ReadVersionAnswer)
           and a.frame.version == b.frame.version, "two 0RV answers differ", a, b)
