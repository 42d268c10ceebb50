"""OUT ports: 0RS reads back what 0WS wrote, for all four values."""

from __future__ import annotations

import pytest

from xac1_proto.dut.evidence import describe_answer, expect
from xac1_proto.frames import ReadOutputs, ReadOutputsAnswer, WriteOutputs


@pytest.mark.parametrize("o", [3, 1, 2, 0])
def test_outputs_read_back(xac1_dut, o):
    """0RS after 0WS with O={id} answers O={id} (docs/protocol.md "Frames", 0WS and 0RS)."""
    w = xac1_dut.send(WriteOutputs(o=o))
    expect(w.answered, f"0WS{o}2 got {describe_answer(w)}", w)
    r = xac1_dut.send(ReadOutputs())
    expect(isinstance(r.frame, ReadOutputsAnswer), f"0RS got {describe_answer(r)}", w, r)
    expect(r.frame.o == o,
           f"0RS after 0WS{o}2: expected O={o}, received O={r.frame.o} ({describe_answer(r)})", w, r)
