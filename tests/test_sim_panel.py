"""The simulator's front panel in-process (``xac1_proto.sim.panel``): the line judged by the one rulebook
whatever the chunking, the state as JSON, the power and stop controls with the facts they pass to the
engine, and the real server (uvicorn on a real port) beside a simulator on a real pty: its page, its
API and its live feed. The page in a real browser: tests/test_sim_panel_browser.py."""

from __future__ import annotations

import json
import socket
import urllib.error
import urllib.request
from collections.abc import Iterator

import pytest
import serial
from conftest import budget, wait_until
from hypothesis import given, settings
from hypothesis import strategies as st

from xac1_proto import frames as fr
from xac1_proto.sim import SimConfig, control, serve_pty
from xac1_proto.sim.model import DeviceModel, PointData
from xac1_proto.sim.panel.line import LineWatch
from xac1_proto.sim.panel.server import Panel, PanelError, panel_for
from xac1_proto.sim.panel.state import state_of

TIMEOUT = 5.0
COMMANDS = [b"0RV\r\n", b"0RC\r\n", b"0RP3\r\n", b"0%C\r\n", b"ORV\r\n", b"0rv\r\n", b"0MV1000\r\n",
            fr.MoveDirect(vel=2, a=1, pos=0x1000).to_bytes(), fr.WriteOutputs(o=3).to_bytes(), b"0RS\r\n",
            b"\x00junk\r\n"]


def _line(commands: list[bytes], deviation: str | None) -> list[tuple[str, bytes]]:
    """A conversation with the simulator's model: each command and its answer, in order."""
    model = DeviceModel(SimConfig(time_scale=0, deviations=frozenset({deviation} if deviation else ())))
    out = []
    for k, command in enumerate(commands):
        model.receive(command, float(k))
        out += [("host", command), ("device", model.outbox.pop(k + 0.5))]
    return out


def _codes(rows: list[dict]) -> list[tuple[str, str, tuple[str, ...]]]:
    return [(r["dir"], r["raw"], tuple(v["code"] for v in r["violations"])) for r in rows]


@settings(max_examples=budget(200))
@given(st.lists(st.sampled_from(COMMANDS), min_size=1, max_size=12),
       st.sampled_from([None, "letter-o", "no-2", "echo-differs", "lf-only"]), st.data())
def test_the_line_is_judged_the_same_whatever_the_chunking(commands, deviation, data):
    """The panel's line view does not depend on how the bytes came: fed in any chunks, it gives the same
    rows (bytes, direction, violation codes) as the line fed one whole line at a time."""
    line = _line(commands, deviation)
    whole, chunked = LineWatch(keep=1000), LineWatch(keep=1000)
    for k, (direction, data_) in enumerate(line):
        whole.feed(float(k), direction, data_)
        cuts = sorted(data.draw(st.lists(st.integers(0, len(data_)), max_size=3)))
        for a, b in zip([0, *cuts], [*cuts, len(data_)], strict=True):
            if a < b:
                chunked.feed(float(k), direction, data_[a:b])
    assert _codes(chunked.rows()) == _codes(whole.rows())
    assert len(whole.rows()) >= len(line)  # every frame or junk run has its row


def test_the_host_mistakes_are_named_as_sniff_names_them():
    """A host's letter-O and lower-case hex are host-side violations with their docs/protocol.md meaning
    and the engine's sentence; the device's letter-o deviation is the device's."""
    watch = LineWatch()
    for k, (direction, data) in enumerate(_line([b"ORV\r\n", b"0%C\r\n"], None)
                                           + _line([b"0RV\r\n"], "letter-o")):
        watch.feed(float(k), direction, data)
    rows = watch.rows()
    host_o = rows[0]["violations"][0]
    seen = (rows[0]["dir"], host_o["code"], host_o["side"], host_o["severity"])
    assert seen == ("host", "letter-o", "host", "error")
    assert host_o["meaning"] and host_o["detail"]
    device_o = [v for r in rows if r["dir"] == "device" for v in r["violations"] if v["code"] == "letter-o"]
    assert device_o and device_o[0]["side"] == "device"


def test_the_state_is_plain_json_and_moves_with_the_axis():
    """``GET /api/state``'s body: every field the issue names, JSON as is; during a move the position is
    where the axis is at that time, between start and target."""
    model = DeviceModel(SimConfig(time_scale=1), {3: PointData(9, 3, 0, 0x1234)})
    model.receive(fr.MoveDirect(vel=1, a=1, pos=0x20000).to_bytes(), 0.0)
    due = model.outbox.next_due
    assert due is not None
    s = state_of(model, due / 2)
    assert {"position", "homed", "alarm", "estop", "outputs", "mode", "points", "deviations"} <= set(s)
    assert json.loads(json.dumps(s)) == s
    assert s["moving"] and s["points"] == {"3": {"v": 9, "a": 3, "o": 0, "pos": 0x1234}}
    assert state_of(model, due + 1)["position"] == 0x20000


def test_power_cycle_is_the_power_on_state_and_keeps_the_table():
    """``power``: not homed, position unknown, mode 0, OUT off, nothing latched, the table kept; twice is
    the same as once (idempotent)."""
    model = DeviceModel(SimConfig(time_scale=0), {1: PointData(1, 1, 0, 5)})
    for k, command in enumerate((fr.MoveDirect(vel=2, a=1, pos=0x1000), fr.WriteOutputs(o=3))):
        model.receive(command.to_bytes(), float(k))
    model.receive(b"0RV 0\r\n", 1.0)  # malformed: alarm 01 latches
    model.outbox.pop(1.0)
    before = state_of(model, 1.0)
    assert before["homed"] and before["outputs"] == 3 and before["alarm"] is not None
    for _ in range(2):
        text, _ = control.apply(model, "power", 2.0)
        after = state_of(model, 2.0)
        assert "power-cycled" in text
        assert (after["homed"], after["position"], after["mode"], after["outputs"], after["alarm"]) == (
            False, None, 0, 0, None)
        assert after["points"] == before["points"]


def test_estop_says_when_it_already_was():
    """Pressing a pressed emergency stop changes nothing and says so (the panel's buttons are idempotent)."""
    model = DeviceModel(SimConfig(time_scale=0))
    assert control.apply(model, "estop on", 0.0)[0] == "emergency stop ON"
    assert control.apply(model, "estop on", 0.0)[0] == "emergency stop ON (it already was)"
    assert control.apply(model, "estop off", 0.0)[0] == "emergency stop off"


# ---- the real server beside a simulator on a real pty ----

@pytest.fixture
def running() -> Iterator[tuple[serial.Serial, Panel]]:
    panel = Panel("127.0.0.1", 0)
    with serve_pty(SimConfig(time_scale=0), on_traffic=panel.tap) as sim, \
            panel_for(sim, panel, control.ControlChannel(sim, panel.fact)), \
            serial.Serial(sim.path, 9600, timeout=TIMEOUT) as port:
        yield port, panel


def _get(panel: Panel, path: str) -> object:
    with urllib.request.urlopen(panel.url + path, timeout=TIMEOUT) as r:
        return json.load(r)


def _post(panel: Panel, command: str, headers: dict[str, str] | None = None) -> tuple[int, dict]:
    request = urllib.request.Request(panel.url + "api/control", data=command.encode(), method="POST",
                                     headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=TIMEOUT) as r:
            return r.status, json.load(r)
    except urllib.error.HTTPError as exc:
        return exc.code, json.load(exc)


def _transact(port: serial.Serial, data: bytes) -> bytes:
    port.write(data)
    return port.read_until(b"\n")


def test_the_api_controls_the_device_the_host_talks_to(running):
    """``POST /api/control`` runs the control channel's command on the device the host talks to:
    ``estop on`` makes the host's next answer 0%%0E; a command that cannot apply is refused (400) with
    the control channel's message and changes nothing; ``GET /api/state`` shows the result."""
    port, panel = running
    assert _transact(port, b"0RV\r\n") == b"0RV100\r\n"
    pressed = {"ok": True, "command": "estop on", "result": "emergency stop ON"}
    assert _post(panel, "estop on") == (200, pressed)
    assert _transact(port, b"0RV\r\n") == b"0%%0E\r\n"
    state = _get(panel, "api/state")
    assert isinstance(state, dict) and state["estop"] and state["alarm"]["code"] == "0E"
    status, body = _post(panel, "fault 77")
    assert status == 400 and not body["ok"] and "one of 09 0B 0A" in body["error"]
    status, body = _post(panel, "replay")
    assert status == 400 and "not replaying a capture" in body["error"]
    assert _post(panel, "estop off")[1]["result"] == "emergency stop off"
    assert _transact(port, b"0RV\r\n") == b"0RV100\r\n"


def test_a_page_of_another_origin_may_not_control_it(running):
    """A web page elsewhere cannot drive the simulator through the user's browser: a control request
    with another Origin is refused (403) and changes nothing; the panel's own origin is served."""
    port, panel = running
    status, body = _post(panel, "estop on", {"Origin": "http://evil.example"})
    assert status == 403 and "may not control" in body["error"]
    assert _transact(port, b"0RV\r\n") == b"0RV100\r\n"
    own = panel.url.rstrip("/")
    assert _post(panel, "estop on", {"Origin": own})[0] == 200


def test_the_stop_input_reaches_the_engine(running):
    """The panel's line view hears the stop input from the control channel, which the line cannot show:
    with the stop pressed, a device that answers a reset ``0%C00`` (the ``estop-cleared`` deviation) is
    named for it (silent item 3), where the bytes alone would not tell; the stop's own answers are clean."""
    port, panel = running
    assert _post(panel, "deviation estop-cleared on")[0] == 200
    _post(panel, "estop on")
    assert _transact(port, b"0RV\r\n") == b"0%%0E\r\n"
    assert _transact(port, b"0%C\r\n") == b"0%C00\r\n"

    def answers() -> list[dict]:
        rows = _get(panel, "api/line")
        assert isinstance(rows, list)
        return [r for r in rows if r["dir"] == "device"]

    rows = wait_until(lambda: len(answers()) >= 2 and answers(), TIMEOUT, "both answers on the line")[-2:]
    assert [r["raw"] for r in rows] == ["'0%%0E' CR LF", "'0%C00' CR LF"]
    assert rows[0]["violations"] == []
    assert [(v["code"], v["side"]) for v in rows[1]["violations"]] == [("estop-cleared", "device")]


def test_the_page_is_self_contained_and_the_feed_is_live(running):
    """``GET /`` is one page that loads nothing from elsewhere (no src or href to another place: it works
    offline); ``GET /api/feed`` is Server-Sent Events whose first event is the state."""
    port, panel = running
    with urllib.request.urlopen(panel.url, timeout=TIMEOUT) as r:
        page = r.read().decode()
    assert "<script>" in page and "EventSource" in page
    assert "src=" not in page.replace('"src="', "") and "http://" not in page and "https://" not in page
    with urllib.request.urlopen(panel.url + "api/feed", timeout=TIMEOUT) as feed:
        assert feed.headers["Content-Type"].startswith("text/event-stream")
        assert feed.readline() == b"event: state\n"
        assert json.loads(feed.readline().removeprefix(b"data: "))["estop"] is False


def test_with_no_browser_the_engine_rests_and_the_history_waits(running):
    """No one looks: the line's bytes are only kept (the engine does not run, so the simulator's thread
    pays one append a chunk); the first look (``GET /api/line``) judges the kept history."""
    port, panel = running
    for command in (b"0RV\r\n", b"ORV\r\n"):
        _transact(port, command)
    rows = wait_until(lambda: len(_get(panel, "api/line")) >= 4 and _get(panel, "api/line"), TIMEOUT,
                      "the four rows of two exchanges")
    assert isinstance(rows, list) and rows[2]["violations"][0]["code"] == "letter-o"
    wait_until(lambda: not panel.judging, TIMEOUT, "the engine to rest with no listener")


def test_a_port_in_use_is_one_clear_error():
    """A panel on a port something listens on is refused naming the address; so is a host that is not."""
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        with pytest.raises(PanelError, match=rf"--panel 127.0.0.1:{port}: the port is in use"):
            Panel("127.0.0.1", port)
    with pytest.raises(PanelError, match="no such host"):
        Panel("no-such-host.invalid", 0)
