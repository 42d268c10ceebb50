"""The host client against the simulator, over a real pty (a thread serving it) and over ``xac1sim://``."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import pytest
import serial
from conftest import wait_until

from sniffer.analyzer import Analyzer
from xac1_proto import (
    AlarmError,
    Client,
    CommunicationHalted,
    ProtocolError,
    ResponseTimeout,
    spec,
)
from xac1_proto import frames as fr
from xac1_proto.chunk import Chunk
from xac1_proto.sim import LineFaults, SimConfig, serve_pty


@dataclass
class Device:
    """A simulator and a way to reach its model (``inject(fn)`` runs ``fn(model, now)``)."""

    url: str
    inject: Callable[[Callable[[Any, float], Any]], Any]


@contextlib.contextmanager
def simulator(kind: str, config: SimConfig) -> Iterator[Device]:
    if kind == "pty":
        with serve_pty(config) as sim:
            yield Device(sim.path, sim.call)
        return
    query = f"time_scale={config.time_scale}&turnaround={config.turnaround_s * 1000}"
    holder: dict[str, Client] = {}

    def inject(fn: Callable[[Any, float], Any]) -> Any:
        return fn(holder["client"].port.model, time.monotonic())

    device = Device(f"xac1sim://?{query}", inject)
    device.holder = holder  # type: ignore[attr-defined]
    yield device


@contextlib.contextmanager
def connect(kind: str, config: SimConfig | None = None, **kwargs: Any) -> Iterator[tuple[Client, Device]]:
    config = config or SimConfig(time_scale=0)
    kwargs.setdefault("time_scale", config.time_scale)
    with simulator(kind, config) as device, Client(device.url, **kwargs) as client:
        if hasattr(device, "holder"):
            device.holder["client"] = client
        yield client, device


KINDS = ["pty", "xac1sim"]


@pytest.mark.parametrize("kind", KINDS)
def test_every_method(kind):
    """Each command method sends its frame and returns the decoded answer (docs/protocol.md "Frames",
    silent items 6, 7, 8, 9)."""
    with connect(kind) as (c, _):
        assert c.read_version() == fr.ReadVersionAnswer(version="100")
        assert c.read_current().pos == spec.UNKNOWN_POSITION  # before homing
        assert c.write_point(1, 9, 3, 2, 0x12345) == fr.WritePointAnswer(n=1, v=9, a=3, o=2, pos=0x12345)
        assert c.read_point(1) == fr.ReadPointAnswer(n=1, v=9, a=3, o=2, pos=0x12345)
        assert c.read_point(2) == fr.ReadPointAnswer(n=2, v=0, a=0, o=0, pos=0)  # never written
        assert c.home() == fr.MovePointAnswer(n=0, v=0, a=0, o=0, pos=0)
        assert c.move_point(1) == fr.MovePointAnswer(n=1, v=9, a=3, o=2, pos=0x12345)
        assert c.read_outputs() == fr.ReadOutputsAnswer(o=2)  # the point's O is set by the move
        assert c.move_direct(30, 2, 5000) == fr.MoveDirectAnswer(vel=30, a=2, pos=5000)
        assert c.position == 5000
        assert c.read_current() == fr.ReadCurrentAnswer(n=0, v=0, a=2, o=2, pos=5000)
        assert c.store_current(3) == fr.StoreCurrentAnswer(n=3, v=0, a=0, o=0, pos=5000)
        assert c.write_outputs(1) == fr.WriteOutputsAnswer(o=1)
        assert c.read_outputs() == fr.ReadOutputsAnswer(o=1)
        assert c.switch_mode(0) == fr.SwitchModeAnswer(mode=0)
        assert c.reset_alarm() == fr.AlarmResetAnswer()
        assert c.request(fr.ReadPoint(n=3)) == fr.ReadPointAnswer(n=3, v=0, a=0, o=0, pos=5000)


@pytest.mark.parametrize("kind", KINDS)
def test_latched_alarm_until_reset(kind):
    """An alarm is latched: every command gets the alarm answer until 0%C, which clears it
    (docs/protocol.md "Behaviour the vendor text states"); AlarmError carries the code and its meaning."""
    with connect(kind) as (c, device):
        device.inject(lambda m, t: m.raise_alarm(spec.ALARM_MEMORY_RW, t))
        for _ in range(2):
            with pytest.raises(AlarmError) as exc:
                c.read_version()
            assert exc.value.code == spec.ALARM_MEMORY_RW
            assert exc.value.meaning == "internal memory read/write error"
            assert exc.value.raw == b"0%%04\r\n"
        assert c.reset_alarm() == fr.AlarmResetAnswer()
        assert c.read_version().version == "100"


@pytest.mark.parametrize("kind", KINDS)
def test_emergency_stop_survives_reset(kind):
    """0%C does not clear emergency stop (0E); releasing the stop input does, and the axis must home
    again (docs/protocol.md "Behaviour the vendor text states", silent item 3)."""
    with connect(kind) as (c, device):
        c.home()
        device.inject(lambda m, t: m.set_estop(True, t))
        for call in (c.read_current, c.reset_alarm):
            with pytest.raises(AlarmError) as exc:
                call()
            assert exc.value.code == spec.ALARM_ESTOP and exc.value.meaning == "emergency stop"
        device.inject(lambda m, t: m.set_estop(False, t))
        c.reset_alarm()
        assert c.read_current().pos == spec.UNKNOWN_POSITION
        assert c.home().pos == 0


def test_move_failure_alarm_forgets_position():
    """A move answered by an alarm (09 limit switch) raises AlarmError; the client no longer claims
    to know where the axis is."""
    with connect("pty") as (c, device):
        c.home()
        device.inject(lambda m, t: m.fail_next_move(spec.ALARM_LIMIT))
        with pytest.raises(AlarmError) as exc:
            c.move_direct(10, 3, 1000)
        assert exc.value.code == spec.ALARM_LIMIT and c.position is None


@pytest.mark.parametrize("kind", KINDS)
def test_storm_guard_halts_until_rearm(kind):
    """After 5 communication-error answers in a row (the reset answer does not end the run) the client
    sends nothing more until rearm() (docs/protocol.md host duty; silent item 1: malformed -> 0%%01)."""
    sent: list[bytes] = []
    with connect(kind, on_traffic=lambda d, data, t: sent.append(data) if d == "host" else None) as (c, _):
        for i in range(4):
            ex = c.transact(b"0RP3\n")  # malformed (bare LF): the device answers 0%%01
            assert ex.alarm is not None and ex.alarm.code == spec.ALARM_COMM
            assert c.comm_errors_in_row == i + 1
        c.reset_alarm()  # the reset answer does not end the run
        assert c.comm_errors_in_row == 4 and not c.halted
        assert c.transact(b"0XX\r\n").alarm == fr.AlarmAnswer(code=spec.ALARM_COMM)
        assert c.halted and c.comm_errors_in_row == 5
        before = len(sent)
        with pytest.raises(CommunicationHalted):
            c.reset_alarm()
        with pytest.raises(CommunicationHalted):
            c.transact(b"0RV\r\n")
        assert len(sent) == before  # nothing went out
        c.rearm()
        c.reset_alarm()
        assert c.read_version().version == "100" and c.comm_errors_in_row == 0


def test_storm_guard_disabled():
    """storm_limit=None never halts."""
    with connect("xac1sim", storm_limit=None) as (c, _):
        for _ in range(7):
            c.transact(b"0RP3\n")
        assert c.comm_errors_in_row == 7 and not c.halted


@pytest.mark.parametrize("kind", KINDS)
def test_slow_turnaround_times_out_and_late_answer_does_not_leak(kind):
    """A late answer raises ResponseTimeout (a TimeoutError); if it arrives after the drain it is
    reported as stale by the next exchange, never taken as that exchange's answer."""
    with connect(kind, timeout=0.1, drain_quiet=0.02) as (c, device):
        device.inject(lambda m, t: setattr(m, "slow_turnaround_s", 0.6))  # well after the drain
        with pytest.raises(TimeoutError) as exc:
            c.read_version()
        assert isinstance(exc.value, ResponseTimeout) and exc.value.partial == b""
        device.inject(lambda m, t: setattr(m, "slow_turnaround_s", 0.0))
        late = len(b"0RV100\r\n")
        wait_until(lambda: c.port.in_waiting >= late, 5, "the late 0RV answer to reach the port")
        ex = c.transact(fr.ReadOutputs().to_bytes())
        assert ex.stale == b"0RV100\r\n"
        assert ex.frame == fr.ReadOutputsAnswer(o=0) and ex.violations == []


def test_dropped_bytes_never_leak_into_the_next_exchange():
    """With bytes dropped on the line each exchange fails on its own (timeout, protocol error) or
    succeeds; once the line is clean again every answer is the right one."""
    with connect("pty", timeout=0.15, drain_quiet=0.02) as (c, device):
        device.inject(lambda m, t: m.set_line_faults(LineFaults(drop=0.15, seed=7)))
        outcomes = set()
        for n in range(1, 16):
            try:
                c.read_point(n)
                outcomes.add("ok")
            except ResponseTimeout:
                outcomes.add("timeout")
            except ProtocolError as exc:
                outcomes.add(exc.code)
        assert outcomes - {"ok"}, "the faults spoiled no answer"
        device.inject(lambda m, t: m.set_line_faults(LineFaults()))
        for n in range(1, 16):
            ex = c.transact(fr.ReadPoint(n=n).to_bytes())
            assert ex.violations == [] and ex.frame == fr.ReadPointAnswer(n=n, v=0, a=0, o=0, pos=0)


def test_everything_dropped_is_a_timeout():
    """No answer at all: ResponseTimeout with nothing partial; the client works once the line does."""
    with connect("pty", timeout=0.1, drain_quiet=0.02) as (c, device):
        device.inject(lambda m, t: m.set_line_faults(LineFaults(drop=1.0)))
        with pytest.raises(ResponseTimeout) as exc:
            c.read_version()
        assert exc.value.partial == b""
        device.inject(lambda m, t: m.set_line_faults(LineFaults()))
        assert c.read_version().version == "100"


@pytest.mark.slow  # a real-time move: seconds
def test_long_move_at_real_time_does_not_time_out():
    """0MP/0MV answer only after the move: a move of about a second at real time (time scale 1) is
    waited for with the rulebook's window (the move's estimated time doubled on top of the timeout; the
    position known from the homing answer), far above the 0.2 s turnaround timeout."""
    with connect("pty", SimConfig(time_scale=1.0), timeout=0.2) as (c, _):
        c.home()  # homing from the sim's 10,000 pulses: about 1.2 s
        command = fr.MoveDirect(vel=10, a=3, pos=5000)  # 5000 pulses at 5000 pulses/s: 1.1 s
        assert c.move_timeout(command) == c.conversation.answer_window(command) > 0.2 + 1.1  # the move fits
        assert c.move_direct(10, 3, 5000).pos == 5000


def sniffed_windows(traffic: list[Chunk], commands: list[fr.Frame]) -> list[float]:
    """The answer window a sniffer's own rulebook, fed the traffic a client saw, gives each command next."""
    analyzer = Analyzer(no_answer_timeout=0.2)
    analyzer.feed_many(iter(traffic), limit=len(traffic) + 1)
    return [analyzer.conversation.answer_window(cmd) for cmd in commands]


@pytest.mark.parametrize("kind", KINDS)
def test_wait_is_the_rulebooks_after_an_emergency_stop_and_for_an_unknown_point(kind):
    """The client waits for a move exactly the answer window a sniffer watching the same line gives it (one
    move-timing model, the rulebook's): before and after an emergency stop, after its release, and for a
    point never read or written, which waits longer than one the answers told."""
    traffic: list[Chunk] = []
    record = lambda d, data, t: traffic.append(Chunk(t, "host" if d == "host" else "device", data))  # noqa: E731
    moves = [fr.MovePoint(n=1), fr.MovePoint(n=5), fr.MovePoint(n=0), fr.MoveDirect(vel=10, a=3, pos=5000)]
    with connect(kind, timeout=0.2, time_scale=1.0, on_traffic=record) as (c, device):
        c.home()
        c.write_point(1, 9, 3, 0, 0x2000)
        c.move_point(1)
        waits = {"homed": [c.move_timeout(m) for m in moves]}
        assert waits["homed"] == sniffed_windows(traffic, moves)
        assert waits["homed"][1] > waits["homed"][0]  # point 5 unknown: priced at its worst
        device.inject(lambda m, t: m.set_estop(True, t))
        with pytest.raises(AlarmError):
            c.read_current()
        waits["stopped"] = [c.move_timeout(m) for m in moves]
        assert waits["stopped"] == sniffed_windows(traffic, moves)
        device.inject(lambda m, t: m.set_estop(False, t))
        c.reset_alarm()
        waits["released"] = [c.move_timeout(m) for m in moves]
        assert waits["released"] == sniffed_windows(traffic, moves)
        assert waits["released"][0] > waits["homed"][0]  # the position is no longer known
        assert c.position is None


def test_protocol_errors_raise_with_code_and_raw():
    """Answers that break the protocol raise ProtocolError (code, raw bytes); transact returns them
    with their violations instead (docs/protocol.md "Violation codes")."""
    cases = [("wrong-length", lambda c: c.read_version(), "bad-length"),
             ("echo-differs", lambda c: c.write_outputs(1), "echo-mismatch"),
             ("wrong-n", lambda c: c.read_point(3), "answer-mismatch")]
    for deviation, call, code in cases:
        with connect("pty") as (c, device):
            device.inject(lambda m, t, d=deviation: m.set_deviation(d))
            with pytest.raises(ProtocolError) as exc:
                call(c)
            assert exc.value.code == code and exc.value.raw
            assert code in [v.code for v in c.transact(b"0RP3\r\n").violations + exc.value.violations]


def test_an_answer_with_the_letter_o_is_a_notice():
    """Vendor §5 states the leading zero of commands only (silent item 21): an answer starting with the
    letter O is read, with a letter-o notice, not raised (issue 35 verdict 9; it raised ProtocolError
    before)."""
    with connect("pty") as (c, device):
        device.inject(lambda m, t: m.set_deviation("letter-o"))
        assert c.read_version()
        exchange = c.transact(b"0RV\r\n")
        assert [(v.code, v.severity) for v in exchange.violations] == [("letter-o", "notice")]
        assert exchange.errors == []


def test_concurrent_callers_never_interleave():
    """Threads sharing a client: one exchange at a time, every caller gets its own answer, and on the
    line each command is followed by its answer before the next command."""
    log: list[tuple[str, bytes]] = []
    with connect("pty", on_traffic=lambda d, data, t: log.append((d, data))) as (c, _):
        for n in range(1, 5):
            c.write_point(n, n, 1, 0, n * 100)
        errors: list[BaseException] = []

        def worker(n: int) -> None:
            try:
                for _ in range(20):
                    assert c.read_point(n).pos == n * 100
            except BaseException as exc:  # noqa: BLE001 - reported by the main thread
                errors.append(exc)

        threads = [threading.Thread(target=worker, args=(n,)) for n in range(1, 5)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
        assert not errors and not any(t.is_alive() for t in threads)
    host = b"".join(data for d, data in log if d == "host")
    device = b"".join(data for d, data in log if d == "device")
    assert host.count(b"\n") == device.count(b"\n") == 84
    runs: list[tuple[str, bytes]] = []  # consecutive chunks of one direction joined
    for d, data in log:
        runs[-1:] = [(d, runs[-1][1] + data)] if runs and runs[-1][0] == d else [*runs[-1:], (d, data)]
    assert [d for d, _ in runs] == ["host", "device"] * 84
    for (_, cmd), (_, answer) in zip(runs[::2], runs[1::2], strict=True):
        assert cmd.count(b"\n") == answer.count(b"\n") == 1 and cmd[:4] == answer[:4]


def test_traffic_hook_and_latency():
    """on_traffic sees every byte in both directions, stamped with the client's clock; latency runs from
    the command's last byte (the host bytes' stamp, ``t_sent``) to the answer's first byte: the answer
    starts in the first chunk received, so its time lies between that chunk's stamp and the next
    chunk's (answers paced at 9600 baud usually come in several chunks)."""
    log: list[tuple[str, bytes, float]] = []
    config = SimConfig(time_scale=0, wire_timing=True)
    with connect("pty", config, on_traffic=lambda d, data, t: log.append((d, data, t))) as (c, _):
        ex = c.transact(b"0RV\r\n")
        returned = time.monotonic()
    host = [(data, t) for d, data, t in log if d == "host"]
    device = [(data, t) for d, data, t in log if d == "device"]
    assert b"".join(data for data, _ in host) == b"0RV\r\n"
    assert b"".join(data for data, _ in device) == b"0RV100\r\n" == ex.raw
    assert [t for _, t in host] == [ex.t_sent]  # the whole command went out at once, stamped t_sent
    assert ex.latency is not None
    first_byte = ex.t_sent + ex.latency
    next_stamp = device[1][1] if len(device) > 1 else returned
    assert device[0][1] <= first_byte <= next_stamp, (ex.t_sent, ex.latency, device)


def test_open_serial_is_set_to_9600_8n1_and_left_open():
    """An open serial.Serial is reconfigured to 9600 8N1; close() leaves it to its owner."""
    with serve_pty(SimConfig(time_scale=0)) as sim:
        port = serial.Serial(sim.path, baudrate=19200, parity=serial.PARITY_EVEN, timeout=1)
        try:
            with Client(port) as c:
                assert (port.baudrate, port.bytesize, port.parity, port.stopbits) == (9600, 8, "N", 1)
                assert c.read_version().version == "100"
            assert port.is_open
        finally:
            port.close()


def test_bad_arguments_raise_before_sending():
    """Out-of-range arguments are refused by the frame classes before anything is sent."""
    sent: list[bytes] = []
    with connect("xac1sim", on_traffic=lambda d, data, t: sent.append(data)) as (c, _):
        with pytest.raises(ValueError, match="field-range"):
            c.read_point(0)
        with pytest.raises(ValueError, match="field-range"):
            c.move_direct(61, 1, 0)
    assert sent == []
