"""The live sniffer on a real Y-cable of pseudo-terminals carrying the simulator and a host: scripted
sloppy hosts and sloppy devices each produce exactly the expected violations (docs/protocol.md "Violation
codes"), and the sniffer never writes to a tap."""

from __future__ import annotations

import contextlib
import threading
import time
from collections import Counter
from dataclasses import replace

import pytest
from conftest import wait_until
from sniffer_wire import ScriptedHost, YCable

from sniffer.analyzer import Analyzer
from sniffer.live import Clock, Session, sniff
from sniffer.order import REORDER_WINDOW_S
from sniffer.records import FrameRecord
from sniffer.taps import ReadOnlyPort, TapWriteError
from xac1_proto.client import Client
from xac1_proto.sim import SimConfig, serve_pty


class Collect:
    def __init__(self) -> None:
        self.records: list = []
        self.summaries: list = []

    def write(self, record) -> None:
        self.records.append(record)

    def summary(self, summary) -> None:
        self.summaries.append(summary)

    def violations(self) -> Counter:
        return Counter(c for r in self.records for c in r.violations)


@contextlib.contextmanager
def line(config: SimConfig | None = None):
    """Simulator + Y-cable + sniffer thread on the taps; yields (sim, cable, collected records).

    The simulator paces its answers at 9600 baud (``wire_timing``) as a real line does: with answers
    sent in no time, a host's next command can reach its tap before the answer it reacts to reaches the
    other tap, and no two-tap sniffer can then tell which came first."""
    config = replace(config or SimConfig(), wire_timing=True)
    with serve_pty(config) as sim, YCable(sim.path) as cable:
        view = Collect()
        analyzer = Analyzer()
        session = Session(analyzer, view)
        clock = Clock()
        stop, started = threading.Event(), threading.Event()
        result: dict = {}
        thread = threading.Thread(target=lambda: result.update(rc=sniff(
            cable.tap_paths, session, clock, stop=stop, started=started)), daemon=True)
        thread.start()
        assert started.wait(5)
        try:
            yield sim, cable, view
        finally:
            wait_until(lambda: all(analyzer.bytes_in(d) >= cable.mirrored[d] for d in ("host", "device")),
                       3, "the sniffer to read every byte mirrored onto the taps")
            stop.set()
            thread.join(5)
            assert not thread.is_alive()
            session.close(clock.now())
        assert result["rc"] == 0
        assert cable.tap_writes == {"host": b"", "device": b""}, "something was written to a tap"
        for d in ("host", "device"):  # every byte accounted for, once (FF too, doubled by PARMRK)
            assert b"".join(r.raw for r in view.records if getattr(r, "raw", None) is not None
                            and r.dir == d) == bytes(cable.seen[d])


def test_client_session_is_clean():
    """The project's client driving the simulator breaks no rule: no violation, every command answered,
    latency measured (docs/protocol.md "Frames")."""
    with line(SimConfig(time_scale=0)) as (sim, cable, view), Client(cable.host_path) as client:
        client.read_version()
        client.write_point(1, 5, 2, 1, 0x1000)
        client.read_point(1)
        client.home()
        client.move_point(1)
        client.read_current()
        client.write_outputs(2)
        client.read_outputs()
        client.reset_alarm()
    assert view.violations() == Counter()
    summary = view.summaries[-1]
    assert summary["frames"] == {"host": 9, "device": 9}
    answers = [r for r in view.records if isinstance(r, FrameRecord) and r.dir == "device"]
    assert all(r.reply_to is not None and r.latency_ms is not None and r.latency_ms >= 0 for r in answers)


def _letter_o(host, sim):
    host.ask(b"ORP1\r\n")
    host.ask(b"0%C\r\n")


def _lower_case(host, sim):
    host.ask(b"0WP1930200abcd\r\n")
    host.ask(b"0%C\r\n")


def _back_to_back(host, sim):
    # A device answering 0.2 s after a command: the second command is on the line well before the first
    # answer (with an answer 0.5 ms after, a busy sniffer reads both taps at once and cannot tell).
    sim.call(lambda model, now: setattr(model, "slow_turnaround_s", 0.2))
    host.ask(b"0RV\r\n0RS\r\n", answers=2)


def _during_move(host, sim):
    host.send(b"0MP0\r\n")
    wait_until(lambda: sim.call(lambda model, now: model.status(now)["moving"]), 3,
               "the homing move to start")
    host.send(b"0RC\r\n")  # discarded by the device during the move (silent item 10)
    host.read_lines(1)
    host.ask(b"0RC\r\n")


def _no_reset(host, sim):
    host.ask(b"0MP1\r\n")  # point 1 never written: alarm 08
    host.ask(b"0RV\r\n")


def _storm(host, sim):
    for _ in range(5):
        host.ask(b"??\r\n")
    host.ask(b"0RV\r\n")  # at the limit: comm-error-storm (and no reset yet: alarm-ignored)
    host.ask(b"0%C\r\n")  # recovering: storm-recovery, and so is the next 0RV
    host.ask(b"0RV\r\n")
    host.ask(b"0RV\r\n")


def _noise(host, sim):
    host.ask(b"\x00\xff0RV\r\n")  # the device reads one malformed line: 0%%01
    host.ask(b"0%C\r\n")


SLOPPY_HOSTS = {
    "letter O": (_letter_o, {"letter-o": 1}),
    "lower case": (_lower_case, {"lowercase-hex": 1}),
    "back-to-back commands": (_back_to_back, {"overlapping-command": 1}),
    "command during a move": (_during_move, {"command-during-motion": 1}),
    "no reset after an alarm": (_no_reset, {"alarm-ignored": 1}),
    "storm of communication errors": (_storm, {"garbage": 5, "comm-error-storm": 1, "alarm-ignored": 1,
                                                "storm-recovery": 2}),
    "noise": (_noise, {"garbage": 1}),
}


@pytest.mark.parametrize("name", SLOPPY_HOSTS)
def test_sloppy_host(name):
    """Each sloppy host habit is named with its docs/protocol.md violation code, and nothing else is."""
    script, expected = SLOPPY_HOSTS[name]
    with line(SimConfig(time_scale=0.25)) as (sim, cable, view):
        host = ScriptedHost(cable.host_path)
        try:
            script(host, sim)
        finally:
            host.close()
    assert view.violations() == Counter(expected)


def _ask_all(*commands):
    def script(host, sim):
        for c in commands:
            host.ask(c)
    return script


def _estop(host, sim):
    sim.call(lambda model, t: model.set_estop(True, t))
    host.ask(b"0RV\r\n")
    host.ask(b"0%C\r\n")


def _silent(host, sim):
    host.send(b"0RP\r\n")  # malformed: the device latches alarm 01 and, with this deviation, says nothing
    wait_until(lambda: sim.call(lambda model, now: model.status(now)["alarm"]), 3, "the device to read 0RP")
    assert sim.call(lambda model, now: model.outbox.next_due) is None, "no answer is on its way"
    # Not synchronisation but the scenario: this host waits out its own timeout. A command sent sooner
    # than the reorder window after an unanswered malformed line is held back by the two-tap sniffer
    # (the line's alarm answer may still come), so that command's answer shows first (sniffer/order.py).
    time.sleep(2 * REORDER_WINDOW_S)
    host.ask(b"0%C\r\n")


SLOPPY_DEVICES = {
    "no-2": (_ask_all(b"0RS\r\n"), {"missing-2": 1, "bad-length": 1}),
    "wrong-length": (_ask_all(b"0RV\r\n"), {"bad-length": 1}),
    "echo-differs": (_ask_all(b"0WS12\r\n"), {"echo-mismatch": 1}),
    "alarm-not-latched": (_ask_all(b"0MP1\r\n", b"0RV\r\n"), {"alarm-ignored": 1, "latch-broken": 1}),
    "wrong-reset-answer": (_ask_all(b"0%C\r\n"), {"field-range": 1}),
    "lf-only": (_ask_all(b"0RV\r\n"), {"bad-length": 1, "bad-terminator": 1}),
    "letter-o": (_ask_all(b"0RV\r\n"), {"letter-o": 1}),
    # the host gave up after 0.3 s, inside the sniffer's 1 s answer window: it overlapped
    "silent-on-malformed": (_silent, {"bad-length": 1, "no-answer": 1, "overlapping-command": 1}),
    "swapped-fields": (_ask_all(b"0WP1930200ABCD\r\n", b"0RP1\r\n"), {"field-range": 1}),
    "wrong-n": (_ask_all(b"0WP1930200ABCD\r\n", b"0RP1\r\n"), {"answer-mismatch": 1}),
    # the line cannot show the stop input: a reset after an unseen release looks the same
    "estop-cleared": (_estop, {"alarm-ignored": 0, "estop-cleared": 0}),
    "write-not-stored": (_ask_all(b"0WP1930200ABCD\r\n", b"0RP1\r\n"), {"readback-mismatch": 1}),
}


@pytest.mark.parametrize("deviation", SLOPPY_DEVICES)
def test_sloppy_device(deviation):
    """Each simulator deviation shows as exactly the violation codes of the rule it breaks (or none when
    it cannot be seen on the line), and nothing else."""
    script, expected = SLOPPY_DEVICES[deviation]
    with line(SimConfig(time_scale=0, deviations=frozenset({deviation}))) as (sim, cable, view):
        host = ScriptedHost(cable.host_path)
        try:
            script(host, sim)
        finally:
            host.close()
    assert view.violations() == Counter({k: v for k, v in expected.items() if v})


def test_tap_is_receive_only(tmp_path):
    """The sniffer never writes to a tap: the port object refuses, and its descriptor is read-only."""
    with serve_pty(SimConfig(time_scale=0)) as sim, YCable(sim.path) as cable:
        port = ReadOnlyPort(cable.tap_paths["host"], "host")
        try:
            with pytest.raises(TapWriteError):
                port.write(b"0RV\r\n")
            with pytest.raises(OSError):
                import os
                os.write(port.fileno(), b"x")
        finally:
            port.close()
        cable.sync()
        assert cable.tap_writes == {"host": b"", "device": b""}
