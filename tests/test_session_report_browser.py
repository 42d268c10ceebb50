"""Session reports opened in real headless Chromium (Debian's ``chromium``, over the DevTools protocol):
the reports of every gallery capture and of a live ``xac1 sniff`` session load with no console error and
no network request, their timeline holds exactly the exchanges and violation marks that ``--format
jsonl`` lists, clicking a mark shows its bytes, and a screenshot is taken and is not blank (issue 17)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from session_report_browser import CHROMIUM, Browser, Page, png_pixels

pytestmark = pytest.mark.slow  # headless chromium per page

ROOT = Path(__file__).resolve().parent.parent
CAPTURES = ROOT / "captures"
XAC1 = [sys.executable, "-m", "xac1_proto"]

if not shutil.which(CHROMIUM):
    if os.environ.get("CI"):
        raise RuntimeError("chromium is missing: .ci/run installs it (Debian package chromium)")
    pytest.skip("chromium is not installed (Debian package chromium)", allow_module_level=True)

# one file a capture: formats with one file per direction are named by their host file
GALLERY = sorted(p.name for p in CAPTURES.iterdir()
                 if p.suffix in (".log", ".txt", ".csv", ".bin", ".pcap", ".pcapng", ".jsonl")
                 and "device" not in p.name)
GALLERY_CODES = {"letter-o", "echo-mismatch", "alarm-ignored", "latch-broken"}


@pytest.fixture(scope="module")
def browser():
    chrome = Browser()
    yield chrome
    chrome.close()


def decode_with_report(capture: Path, out: Path) -> list[dict]:
    """``xac1 decode CAPTURE --format jsonl --report OUT``: the JSON lines it printed."""
    done = subprocess.run([*XAC1, "decode", str(capture), "--format", "jsonl", "--report", str(out)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert done.returncode in (0, 1), done.stderr
    return [json.loads(line) for line in done.stdout.splitlines()]


COUNT_PLOTTED = """(() => {
  const gd = document.getElementById("timeline");
  const traces = gd.data;
  const exchanges = traces.filter(t => t.meta === "exchanges")
                          .reduce((n, t) => n + t.x.filter(v => v === null).length, 0);
  const codes = {};
  for (const t of traces.filter(t => t.meta === "violation")) codes[t.text[0]] = t.x.length;
  const drawn = gd.querySelectorAll(".scatterlayer .trace .points path.point").length;
  const unanswered = traces.filter(t => t.meta === "unanswered")
                           .reduce((n, t) => n + t.x.filter(v => v === null).length, 0);
  const lanes = ["host-frame", "device-frame", "host-junk", "device-junk"];
  const frames = traces.filter(t => lanes.includes(t.meta))
                       .reduce((n, t) => n + t.x.length, 0);
  const plots = Array.from(document.querySelectorAll(".plot")).map(el => [el.id, !!el._fullLayout]);
  return {exchanges, unanswered, codes, drawn, frames, plots};
})()"""


def check_page(page: Page, lines: list[dict]) -> dict:
    """No console problem, no request; the timeline holds the exchanges, frames and marks of ``lines``."""
    assert page.problems() == []
    assert page.requests() == []
    plotted = page.evaluate(COUNT_PLOTTED)
    records = [r for r in lines if r["type"] != "summary"]
    exchanges = sum(1 for r in records if r["type"] == "frame" and r["dir"] == "device"
                    and r["reply_to"] is not None)
    codes: dict[str, int] = {}
    for r in records:
        for code in r["violations"]:
            codes[code] = codes.get(code, 0) + 1
    frames = sum(1 for r in records if r["type"] in ("frame", "junk"))
    assert plotted["exchanges"] == exchanges
    assert plotted["unanswered"] == sum(1 for r in records if r["type"] == "timeout")
    assert plotted["codes"] == codes
    assert plotted["frames"] == frames
    assert plotted["drawn"] == frames + sum(codes.values())  # every point really drawn in the SVG
    assert all(ready for _, ready in plotted["plots"]), plotted["plots"]
    return plotted


def check_screenshot(page: Page, path: Path | None = None) -> None:
    png = page.screenshot()
    if path is not None:
        path.write_bytes(png)
    width, height, colours = png_pixels(png)
    commonest = colours.most_common(1)[0][1]
    assert (width, height) == (1280, 900)
    assert len(colours) > 50 and commonest < 0.9 * width * height, (len(colours), commonest)


@pytest.mark.parametrize("name", GALLERY)
def test_gallery_capture_report_in_chromium(browser, tmp_path, name):
    """Each gallery capture's report: loads clean and offline, the timeline has one line per answered
    command and one mark per violation of the decoded records (the gallery's sloppy host and faulty
    device: captures/README.md), and the screenshot is not blank."""
    out = tmp_path / "report.html"
    lines = decode_with_report(CAPTURES / name, out)
    page = browser.open(out)
    try:
        plotted = check_page(page, lines)
        assert set(plotted["codes"]) >= GALLERY_CODES
        check_screenshot(page)
    finally:
        page.close()


def test_clicking_a_mark_shows_its_record(browser, tmp_path):
    """Clicking the echo-mismatch mark of socat-xv.log's timeline shows that answer's bytes, fields and
    the violation with its meaning, as ``xac1 decode`` gives them."""
    out = tmp_path / "report.html"
    lines = decode_with_report(CAPTURES / "socat-xv.log", out)
    [echo] = [r for r in lines if r["type"] == "frame" and "echo-mismatch" in r["violations"]]
    page = browser.open(out)
    try:
        where = page.evaluate("""(() => {
          const gd = document.getElementById("timeline");
          const k = gd.data.findIndex(t => t.meta === "violation" && t.text[0] === "echo-mismatch");
          const point = gd.querySelectorAll(".scatterlayer .trace")[k].querySelector("path.point");
          point.scrollIntoView({block: "center"});
          const box = point.getBoundingClientRect();
          return [box.x + box.width / 2, box.y + box.height / 2];
        })()""")
        page.click(*where)
        shown = page.evaluate("document.getElementById('detail').textContent")
        assert f"#{echo['i']}  device frame" in shown
        assert "bytes:  0WP19302012344\\r\\n" in shown
        assert "pos=74564" in shown and f"answers #{echo['reply_to']}" in shown
        assert "echo-mismatch (error): an echo answer differs from its command" in shown
        assert page.problems() == []
    finally:
        page.close()


OVERLAPS = """((id) => {
  const boxes = Array.from(document.querySelectorAll(`#${id} .textpoint text, #${id} .scatterlayer text`))
    .map(t => t.getBoundingClientRect()).filter(b => b.width > 0);
  let pairs = 0;
  for (let a = 0; a < boxes.length; a++) for (let b = a + 1; b < boxes.length; b++) {
    const p = boxes[a], q = boxes[b];
    if (p.left < q.right && q.left < p.right && p.top < q.bottom && q.top < p.bottom) pairs++;
  }
  return pairs;
})"""


def test_close_marks_are_readable_and_no_position_is_drawn_before_one_is_known(browser, tmp_path):
    """A ten-minute session with marks 0.2 s apart (lower-case hex, an ignored alarm, a letter O on an
    overlapping command): no text drawn on the timeline or the position plot overlaps another (the
    codes' labels did, issue 40 item 8); pointing at a mark shows its code and meaning; the alarm
    answers, which came before any position was known, are in the strip above the position axis."""
    from test_session_report import CLOSE_MARKS

    from xac1_proto.chunk import Chunk
    from xac1_proto.recording import RecordingWriter

    capture, out = tmp_path / "close.jsonl", tmp_path / "report.html"
    with RecordingWriter(capture) as rec:
        for t, d, raw in CLOSE_MARKS:
            rec.write(Chunk(1_795_000_000.0 + t, d, raw))
    lines = decode_with_report(capture, out)
    page = browser.open(out)
    try:
        check_page(page, lines)
        assert page.evaluate(f"{OVERLAPS}('timeline')") == 0
        assert page.evaluate(f"{OVERLAPS}('position')") == 0
        shown = page.evaluate("""(() => {
          const gd = document.getElementById("timeline");
          const k = gd.data.findIndex(t => t.meta === "violation" && t.text[0] === "overlapping-command");
          Plotly.Fx.hover(gd, [{curveNumber: k, pointNumber: 0}]);
          return gd.querySelector(".hoverlayer").textContent;
        })()""")
        assert "overlapping-command (host): a new command before the previous answer" in shown
        strip = page.evaluate("""(() => {
          const gd = document.getElementById("position");
          return gd.data.filter(t => t.meta === "alarm").map(t => [t.yaxis, t.x.length]);
        })()""")
        assert strip == [["y2", 2]]
        check_screenshot(page, tmp_path / "close.png")
    finally:
        page.close()


def test_live_sniffer_session_report_in_chromium(browser, tmp_path):
    """``xac1 sniff --report`` over a real Y-cable of ptys, the simulator as the device (echoing 0WP
    wrongly) and the client as the host (a letter-O command, homing, a move): after Ctrl-C the report is
    written; in Chromium it loads clean, holds every exchange and violation the sniffer printed, draws
    the axis position with the homing and the move (from the start the engine knew), and its screenshot
    is not blank."""
    from sniffer_wire import YCable
    from test_sniffer_cli import Cli, no_traceback

    from xac1_proto.client import Client
    from xac1_proto.sim import SimConfig, serve_pty

    out = tmp_path / "live.html"
    config = SimConfig(time_scale=0.02, deviations=frozenset({"echo-differs"}))
    with serve_pty(config) as sim, YCable(sim.path) as cable, \
            Cli("sniff", "--host-tap", cable.tap_paths["host"], "--device-tap", cable.tap_paths["device"],
                "--format", "jsonl", "--report", str(out)) as cli:
        cli.wait_err("Ctrl-C to stop")
        with Client(cable.host_path, time_scale=0.02) as client:
            client.read_version()
            client.transact(b"ORV\r\n")  # letter O: alarm 01 answers
            client.reset_alarm()
            client.home()
            client.read_current()  # the engine learns where homing left the axis (silent item 7)
            client.transact(b"0WP19302004000\r\n")  # the device echoes it wrongly (echo-differs)
            client.move_point(1)
            client.read_current()
            cli.records(16)  # every frame seen live before stopping
        assert cli.finish() == 0
        no_traceback(cli)
    assert any("report written to" in line for line in cli.stderr), cli.stderr
    lines = cli.all_records()
    page = browser.open(out)
    try:
        plotted = check_page(page, lines)
        assert {"letter-o", "echo-mismatch"} <= set(plotted["codes"])
        axis = page.evaluate("""(() => {
          const gd = document.getElementById("position");
          const by = name => gd.data.find(t => t.name.startsWith(name));
          return {positions: by("position answered").y, homing: by("homing").x.length,
                  moves: by("move").x.filter(v => v === null).length};
        })()""")
        # homing (from an unknown position: not drawn as a move), 0RC, the move to point 1 from where the
        # engine knew the axis (the report asks it), then 0RC
        assert axis["positions"] == [0, 0, 0x4000, 0x4000] and axis["homing"] == 1 and axis["moves"] == 1
        check_screenshot(page, tmp_path / "live.png")
    finally:
        page.close()


def test_hostile_bytes_stay_data(browser, tmp_path):
    """Bytes on the line that look like HTML (``</script><script>...``) are shown as the bytes they are:
    the page's embedded JSON cannot be closed by them, no script of theirs runs, the detail shows them."""
    capture, out = tmp_path / "hostile.jsonl", tmp_path / "hostile.html"
    hostile = b"</script><script>window.pwned=1</script><!--\r\n"
    rows = [{"type": "recording", "version": 1, "started": 1714557600.0, "source": "t"},
            {"type": "chunk", "t": 1714557600.0, "dir": "host", "data": hostile.hex()},
            {"type": "chunk", "t": 1714557600.1, "dir": "host", "data": b"0RV\r\n".hex()},
            {"type": "chunk", "t": 1714557600.12, "dir": "device", "data": b"0RV100\r\n".hex()}]
    capture.write_text("".join(json.dumps(row) + "\n" for row in rows), encoding="ascii")
    lines = decode_with_report(capture, out)
    page = browser.open(out)
    try:
        check_page(page, lines)
        assert page.evaluate("window.pwned === undefined")
        page.evaluate("window.xac1Session.show(0)")
        shown = page.evaluate("document.getElementById('detail').textContent")
        assert "bytes:  </script><script>window.pwned=1</script><!--\\r\\n" in shown
        assert "garbage (error): bytes that form no frame" in shown
    finally:
        page.close()
