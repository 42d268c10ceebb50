"""Random command sequences checked against the reference model of the stated rules.

A hypothesis rule machine sends valid commands (reads, writes inside the safe range, moves when allowed,
OUT ports, mode, version), malformed commands and resets, in random order, and judges each answer with
``conformance.model.Model``. The number of sequences is bounded (``--xac1-examples``) and the sequences
are reproducible from the seed (``--xac1-seed``, default 0). A sequence never puts more than four
communication-error answers in a row (the vendor's host duty). Shrinking is off: on a real device a
replay starts from another state, so the first failing sequence is the one reported.
"""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, Phase, seed, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, get_state_machine_test, precondition, rule

from conformance.dut import DeviceAbort
from conformance.evidence import Probe, RuleBroken, describe_answer
from conformance.kit import MALFORMED
from conformance.model import Model, Point
from conformance.safety import POINTS
from xac1_proto import spec
from xac1_proto.frames import (
    AlarmReset,
    Frame,
    MoveDirect,
    MovePoint,
    ReadCurrent,
    ReadOutputs,
    ReadPoint,
    ReadPointAnswer,
    ReadVersion,
    StoreCurrent,
    SwitchMode,
    WriteOutputs,
    WritePoint,
)

pytestmark = pytest.mark.xac1_last
MAX_ALARMS_IN_ROW = spec.STORM_LIMIT - 1


def _initial_model(dut) -> Model:
    points = {}
    for n in POINTS:
        p = dut.send(ReadPoint(n=n))
        if not isinstance(p.frame, ReadPointAnswer) or p.errors:
            raise RuleBroken(f"0RP{n:X} got {describe_answer(p)}", [p])
        f = p.frame
        points[n] = Point(f.v, f.a, f.o, f.pos)
    model = Model(points=points, outputs=None, version=dut.version)
    for command in (ReadOutputs(), ReadCurrent()):
        p = dut.send(command)
        problems = model.judge(command, p.frame, p.raw, [str(e) for e in p.errors])
        if problems:
            raise RuleBroken("; ".join(problems), [p])
    return model


def test_random_sequences(xac1_dut, xac1_kit, xac1_settings):
    """Random sequences of commands get the answers a reference model of the stated rules predicts: echoes,
    read-back, latched alarms, reset, positions after moves (docs/protocol.md "Frames"; "Behaviour the vendor
    text states")."""
    dut, s = xac1_dut, xac1_settings
    xac1_kit.point(0)  # at least one point to write (NotEnoughPoints: skipped, saying what to pass)
    model = _initial_model(dut)
    kit_points = xac1_kit.scratch
    if s.safe_range is not None:
        positions = st.integers(*s.safe_range)
    else:  # no motion: only positions the points already held
        positions = st.sampled_from(sorted({p.pos for p in xac1_kit.snapshot.points.values()}))
    first_failure: list[RuleBroken] = []
    bad_commands = [m for m in MALFORMED if not m.moves]

    def may_send(_machine: object) -> bool:
        return model.latched is None or model.comm_errors_in_row < MAX_ALARMS_IN_ROW

    def movable() -> list[int]:
        return [n for n in sorted(model.written) if s.in_range(model.points[n].pos)]

    def may_move(_machine: object) -> bool:
        return s.motion and may_send(_machine) and (model.homed is True or s.may_home)

    start_points = xac1_kit.scratch[:4]

    class Sequences(RuleBasedStateMachine):
        def __init__(self) -> None:
            super().__init__()
            self.steps: list[Probe] = []
            self._start()

        def _start(self) -> None:
            """Every sequence starts from the same state (hypothesis needs the same choices to meet the
            same preconditions): no alarm, four known points, the OUT ports as found, the axis at the
            safe range's low end when the run may move."""
            if model.latched is not None or model.comm_errors_in_row:
                self.send(AlarmReset())
                self.send(ReadVersion())
            model.written.clear()
            for k, n in enumerate(start_points):
                pos = s.safe_range[0] + k if s.safe_range else xac1_kit.snapshot.points[n].pos
                self.send(WritePoint(n=n, v=9 - k, a=1 + k % 3, o=k % 4, pos=pos))
            self.send(WriteOutputs(o=xac1_kit.snapshot.outputs))
            if s.motion and (model.homed is True or s.may_home):
                self.send(MoveDirect(vel=0x3C, a=3, pos=s.safe_range[0]))
            self.steps.clear()

        def _judge(self, command: Frame | bytes, p: Probe) -> None:
            self.steps.append(p)
            errors = [str(e) for e in p.errors]
            if p.timed_out:
                errors.append("no answer (silence)")
            problems = model.judge(command, p.frame, p.raw, errors)
            if problems:
                failure = RuleBroken(f"step {len(self.steps)}: {'; '.join(problems)}", self.steps[-10:])
                if not first_failure:
                    first_failure.append(failure)
                raise failure

        def send(self, command: Frame) -> None:
            self._judge(command, dut.send(command))

        @precondition(may_send)
        @rule(n=st.sampled_from(list(POINTS)))
        def read_point(self, n: int) -> None:
            self.send(ReadPoint(n=n))

        @precondition(may_send)
        @rule(n=st.sampled_from(kit_points[:4]), v=st.integers(1, 9), a=st.integers(1, 3),
              o=st.integers(0, 3), pos=positions)
        def write_point(self, n: int, v: int, a: int, o: int, pos: int) -> None:
            self.send(WritePoint(n=n, v=v, a=a, o=o, pos=pos))

        @precondition(may_send)
        @rule()
        def read_current(self) -> None:
            self.send(ReadCurrent())

        @precondition(lambda m: may_send(m) and model.homed is True and model.position is not None)
        @rule(n=st.sampled_from(kit_points[:4]))
        def store_current(self, n: int) -> None:
            self.send(StoreCurrent(n=n))

        @precondition(lambda m: may_move(m) and bool(movable()))
        @rule(data=st.data())
        def move_point(self, data: st.DataObject) -> None:
            self.send(MovePoint(n=data.draw(st.sampled_from(movable()), label="n")))

        @precondition(lambda m: may_move(m) and s.may_home)
        @rule()
        def home(self) -> None:
            self.send(MovePoint(n=0))

        @precondition(may_move)
        @rule(vel=st.integers(0x1E, 0x3C), a=st.integers(1, 3), pos=positions)
        def move_direct(self, vel: int, a: int, pos: int) -> None:
            self.send(MoveDirect(vel=vel, a=a, pos=pos))

        @precondition(may_send)
        @rule()
        def read_outputs(self) -> None:
            self.send(ReadOutputs())

        @precondition(may_send)
        @rule(o=st.integers(0, 3))
        def write_outputs(self, o: int) -> None:
            self.send(WriteOutputs(o=o))

        @precondition(may_send)
        @rule()
        def read_version(self) -> None:
            self.send(ReadVersion())

        @precondition(may_send)
        @rule(mode=st.sampled_from([1, 0]))
        def switch_mode(self, mode: int) -> None:
            self.send(SwitchMode(mode=mode))

        @precondition(lambda m: model.latched is None and model.comm_errors_in_row < MAX_ALARMS_IN_ROW)
        @rule(bad=st.sampled_from(bad_commands))
        def malformed(self, bad) -> None:
            raw = bad.make(xac1_kit)
            self._judge(raw, dut.probe(raw))

        @rule()
        def reset(self) -> None:
            self.send(AlarmReset())


    config = settings(max_examples=s.examples, stateful_step_count=15 if s.simulator else 8, deadline=None,
                      database=None, phases=(Phase.explicit, Phase.generate), print_blob=False,
                      suppress_health_check=list(HealthCheck), derandomize=False)
    run = seed(s.seed)(get_state_machine_test(Sequences, settings=config))
    try:
        run()
    except DeviceAbort:
        raise  # the run stops (the device went away): not a verdict on the sequences
    except Exception:
        if first_failure:
            raise first_failure[0] from None
        raise
