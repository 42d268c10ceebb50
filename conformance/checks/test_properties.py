"""Random command sequences judged by the one rulebook (``xac1_proto.conversation``, through the client).

``Sequences`` is a hypothesis rule machine that sends valid commands (reads, writes inside the safe
range, moves when allowed, OUT ports, mode, version), malformed commands and resets, in random order;
the device, the kit, the settings and the model are injected (``Sequences.bound``). Each answer gets the
engine's verdict (``conformance.model.Model.judge``): echoes by fields, read-back of points, OUT ports,
position and version, latched alarms, the reset, errors answered with an alarm answer. The number of
sequences is bounded (``--xac1-examples``) and reproducible from the seed (``--xac1-seed``, default 0).
A sequence never puts more than four communication-error answers in a row (the vendor's host duty).
Shrinking is off: on a real device a replay starts from another state, so the first failing sequence
is the one reported. A device or port that fails during a sequence (``DeviceAbort``) is no failing
example: it leaves hypothesis at once (``DeviceGone``, which hypothesis does not catch, so it never
replays the sequence on a dead port) and ends the run as any check's would.
"""

from __future__ import annotations

from typing import Any, ClassVar

import pytest
from hypothesis import HealthCheck, Phase, seed, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, get_state_machine_test, precondition, rule

from conformance.kit import MALFORMED
from conformance.model import Model
from xac1_proto import spec
from xac1_proto.dut.device import DeviceAbort
from xac1_proto.dut.evidence import Probe, RuleBroken, describe_answer
from xac1_proto.dut.safety import POINTS
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


class DeviceGone(BaseException):
    """Carries a ``DeviceAbort`` out of hypothesis (which takes every ``Exception`` for a failing example
    and replays it) to the check, which raises the abort itself."""

    def __init__(self, abort: DeviceAbort) -> None:
        super().__init__(str(abort))
        self.abort = abort


class Sequences(RuleBasedStateMachine):
    """One random sequence: a rule a command kind; every answer judged by the model (the engine)."""

    dut: ClassVar[Any]
    kit: ClassVar[Any]
    s: ClassVar[Any]
    model: ClassVar[Model]
    failures: ClassVar[list[RuleBroken]]

    @classmethod
    def bound(cls, dut: Any, kit: Any, s: Any, model: Model) -> type[Sequences]:
        """This machine with its device, kit, settings and model injected."""
        return type("Sequences", (cls,), {"dut": dut, "kit": kit, "s": s, "model": model, "failures": []})

    def __init__(self) -> None:
        super().__init__()
        self.steps: list[Probe] = []
        self._start()

    # ---- what may be sent ----

    def may_send(self) -> bool:
        return self.model.latched is None or self.model.comm_errors_in_row < MAX_ALARMS_IN_ROW

    def movable(self) -> list[int]:
        m = self.model
        return [n for n in sorted(m.written) if (p := m.point(n)) is not None and self.s.in_range(p.pos)]

    def may_move(self) -> bool:
        return self.s.motion and self.may_send() and (self.model.homed is True or self.s.may_home)

    def positions(self) -> st.SearchStrategy[int]:
        if self.s.safe_range is not None:
            return st.integers(*self.s.safe_range)
        # no motion: only positions the points already held
        return st.sampled_from(sorted({p.pos for p in self.kit.snapshot.points.values()}))

    def scratch(self) -> list[int]:
        return list(self.kit.scratch[:4])

    # ---- sending and judging ----

    def _start(self) -> None:
        """Every sequence starts from the same state (hypothesis needs the same choices to meet the same
        preconditions): no alarm, four known points, the OUT ports as found, the axis at the safe range's
        low end when the run may move."""
        m, s = self.model, self.s
        if m.latched is not None or m.comm_errors_in_row:
            self.send(AlarmReset())
            self.send(ReadVersion())
        m.written.clear()
        for k, n in enumerate(self.scratch()):
            pos = s.safe_range[0] + k if s.safe_range else self.kit.snapshot.points[n].pos
            self.send(WritePoint(n=n, v=9 - k, a=1 + k % 3, o=k % 4, pos=pos))
            m.written.add(n)
        self.send(WriteOutputs(o=self.kit.snapshot.outputs))
        if s.motion and (m.homed is True or s.may_home):
            self.send(MoveDirect(vel=0x3C, a=3, pos=s.safe_range[0]))
        self.steps.clear()

    def judge(self, p: Probe) -> None:
        self.steps.append(p)
        problems = self.model.judge(p)
        if problems:
            failure = RuleBroken(f"step {len(self.steps)}: {'; '.join(problems)}", self.steps[-10:])
            if not self.failures:
                self.failures.append(failure)
            raise failure

    def send(self, command: Frame) -> None:
        self.judge(self._ask(self.dut.send, command))

    def _ask(self, ask: Any, what: Any) -> Probe:
        """``ask(what)`` of the device; a device or port that failed leaves hypothesis at once."""
        try:
            return ask(what)
        except DeviceAbort as exc:
            raise DeviceGone(exc) from exc

    # ---- rules ----

    @precondition(lambda m: m.may_send())
    @rule(n=st.sampled_from(list(POINTS)))
    def read_point(self, n: int) -> None:
        self.send(ReadPoint(n=n))

    @precondition(lambda m: m.may_send())
    @rule(data=st.data(), v=st.integers(1, 9), a=st.integers(1, 3), o=st.integers(0, 3))
    def write_point(self, data: st.DataObject, v: int, a: int, o: int) -> None:
        n = data.draw(st.sampled_from(self.scratch()), label="n")
        self.send(WritePoint(n=n, v=v, a=a, o=o, pos=data.draw(self.positions(), label="pos")))
        self.model.written.add(n)

    @precondition(lambda m: m.may_send())
    @rule()
    def read_current(self) -> None:
        self.send(ReadCurrent())

    @precondition(lambda m: m.may_send() and m.model.homed is True and m.model.position is not None)
    @rule(data=st.data())
    def store_current(self, data: st.DataObject) -> None:
        n = data.draw(st.sampled_from(self.scratch()), label="n")
        self.send(StoreCurrent(n=n))
        self.model.written.add(n)

    @precondition(lambda m: m.may_move() and bool(m.movable()))
    @rule(data=st.data())
    def move_point(self, data: st.DataObject) -> None:
        self.send(MovePoint(n=data.draw(st.sampled_from(self.movable()), label="n")))

    @precondition(lambda m: m.may_move() and m.s.may_home)
    @rule()
    def home(self) -> None:
        self.send(MovePoint(n=0))

    @precondition(lambda m: m.may_move())
    @rule(data=st.data(), vel=st.integers(0x1E, 0x3C), a=st.integers(1, 3))
    def move_direct(self, data: st.DataObject, vel: int, a: int) -> None:
        self.send(MoveDirect(vel=vel, a=a, pos=data.draw(self.positions(), label="pos")))

    @precondition(lambda m: m.may_send())
    @rule()
    def read_outputs(self) -> None:
        self.send(ReadOutputs())

    @precondition(lambda m: m.may_send())
    @rule(o=st.integers(0, 3))
    def write_outputs(self, o: int) -> None:
        self.send(WriteOutputs(o=o))

    @precondition(lambda m: m.may_send())
    @rule()
    def read_version(self) -> None:
        self.send(ReadVersion())

    @precondition(lambda m: m.may_send())
    @rule(mode=st.sampled_from([1, 0]))
    def switch_mode(self, mode: int) -> None:
        self.send(SwitchMode(mode=mode))

    @precondition(lambda m: m.model.latched is None and m.model.comm_errors_in_row < MAX_ALARMS_IN_ROW)
    @rule(bad=st.sampled_from([m for m in MALFORMED if not m.moves]))
    def malformed(self, bad: Any) -> None:
        self.judge(self._ask(self.dut.probe, bad.make(self.kit)))

    @rule()
    def reset(self) -> None:
        self.send(AlarmReset())


def _start_model(dut: Any) -> Model:
    """The model is the client's conversation; it reads every point, the OUT ports and the position
    first, so what follows is judged against what the device said (learnt) or was told (known)."""
    model = Model(dut.client.conversation)
    for n in POINTS:
        p = dut.send(ReadPoint(n=n))
        if not isinstance(p.frame, ReadPointAnswer) or p.errors:
            raise RuleBroken(f"0RP{n:X} got {describe_answer(p)}", [p])
    for command in (ReadOutputs(), ReadCurrent()):
        p = dut.send(command)
        problems = model.judge(p)
        if problems:
            raise RuleBroken("; ".join(problems), [p])
    return model


def test_random_sequences(xac1_dut, xac1_kit, xac1_settings):
    """Random sequences of commands get the verdicts of the one rulebook: echoes, read-back, latched
    alarms, reset, positions after moves (docs/protocol.md "Frames"; "Behaviour the vendor text
    states")."""
    dut, s = xac1_dut, xac1_settings
    xac1_kit.point(0)  # at least one point to write (NotEnoughPoints: skipped, saying what to pass)
    machine = Sequences.bound(dut, xac1_kit, s, _start_model(dut))
    config = settings(max_examples=s.examples, stateful_step_count=15 if s.simulator else 8, deadline=None,
                      database=None, phases=(Phase.explicit, Phase.generate), print_blob=False,
                      suppress_health_check=list(HealthCheck), derandomize=False)
    run = seed(s.seed)(get_state_machine_test(machine, settings=config))
    try:
        run()
    except DeviceGone as gone:
        raise gone.abort from None  # the run stops (the device went away): not a verdict on the sequences
    except DeviceAbort:
        raise
    except Exception:
        if machine.failures:
            raise machine.failures[0] from None
        raise
