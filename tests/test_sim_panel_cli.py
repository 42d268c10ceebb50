"""``xac1 sim --panel`` as a user runs it: the front panel in the Debian chromium (driven by Playwright)
beside a host script on the pty; a panel address that cannot be served; ``--deviation list`` without a
transport (issue 40 item 10).

The browser test also takes the guide's screenshot: with ``XAC1_SCREENSHOTS=DIR`` set it is written to
``DIR/simulator-panel.png`` (``XAC1_SCREENSHOTS=docs pytest tests/test_sim_panel_cli.py`` renews
docs/simulator-panel.png)."""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
from pathlib import Path

import pytest
import serial
from conftest import xac1, xac1_sim

from xac1_proto import frames as fr
from xac1_proto.sim.config import DEVIATIONS, ROBUSTNESS, ROBUSTNESS_MARK

TIMEOUT = 5.0
MS = 5000  # Playwright's waits, in milliseconds


def _panel_url(proc: subprocess.Popen[str]) -> str:
    """The panel's address, from the line ``xac1 sim`` writes on stderr once it serves."""
    assert proc.stderr is not None
    for _ in range(5):
        found = re.search(r"front panel at (\S+)", proc.stderr.readline())
        if found:
            return found.group(1)
    raise AssertionError("xac1 sim never said where its front panel is")


def _transact(port: serial.Serial, data: bytes) -> bytes:
    port.write(data)
    return port.read_until(b"\n")


@pytest.mark.slow
@pytest.mark.requires_tool("chromium")
def test_the_panel_in_chromium_follows_and_drives_the_line(tmp_path: Path) -> None:
    """In a real browser: a move the host script makes shows on the page as the new position; the page's
    emergency stop makes the host's next answer ``0%%0E`` and the page says what it did; a deviation
    switched on from the page breaks its rule in the host's next answer, and the page's line shows the
    engine's verdict on it (letter-o, the device's fault)."""
    from playwright.sync_api import expect, sync_playwright

    with xac1_sim("--pty", "--time-scale", "0", "--panel", "127.0.0.1:0") as (proc, path), \
            serial.Serial(path, 9600, timeout=TIMEOUT) as port, sync_playwright() as pw:
        url = _panel_url(proc)
        browser = pw.chromium.launch(executable_path=shutil.which("chromium"))
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 1000})
            page.goto(url)
            expect(page.locator("#feed")).to_have_text("live", timeout=MS)
            expect(page.locator("#position")).to_have_text("unknown (FFFFFF)", timeout=MS)

            assert _transact(port, fr.MoveDirect(vel=2, a=1, pos=0x1000).to_bytes()).startswith(b"0MV")
            expect(page.locator("#position")).to_have_text("001000 (4096)", timeout=MS)
            expect(page.locator("#homed")).to_have_text("yes", timeout=MS)

            page.click("#estop-button")
            expect(page.locator("#result")).to_contain_text("emergency stop ON", timeout=MS)
            expect(page.locator("#estop")).to_have_text("PRESSED", timeout=MS)
            assert _transact(port, b"0RV\r\n") == b"0%%0E\r\n"
            page.click("#estop-button")
            expect(page.locator("#result")).to_contain_text("emergency stop off", timeout=MS)
            expect(page.locator("#estop")).to_have_text("released", timeout=MS)

            page.check("#deviations input[data-name='letter-o']")
            expect(page.locator("#result")).to_contain_text("deviation letter-o on", timeout=MS)
            answer = _transact(port, b"0RV\r\n")
            assert answer.startswith(b"O") and answer != b"0RV100\r\n"
            verdict = page.locator("#line [data-code='letter-o']").first
            expect(verdict).to_contain_text("device ✗ letter-o", timeout=MS)

            page.fill("#command", "fault 77")
            page.click("#send")
            refused = "refused: fault CODE: one of 09 0B 0A"
            expect(page.locator("#result")).to_contain_text(refused, timeout=MS)
            page.fill("#command", "status")
            page.click("#send")
            expect(page.locator("#result")).to_contain_text("deviations: letter-o", timeout=MS)

            for command in (fr.WritePoint(n=3, v=5, a=2, o=1, pos=0x7FF000),
                            fr.MoveDirect(vel=5, a=2, pos=0xA00000)):
                _transact(port, command.to_bytes())
            expect(page.locator("#position")).to_have_text("A00000 (10485760)", timeout=MS)
            expect(page.locator("#points")).to_contain_text("7FF000", timeout=MS)
            shot = tmp_path / "simulator-panel.png"
            page.screenshot(path=str(shot), full_page=True)
            assert shot.read_bytes().startswith(b"\x89PNG")
            if os.environ.get("XAC1_SCREENSHOTS"):
                shutil.copy(shot, Path(os.environ["XAC1_SCREENSHOTS"]) / shot.name)
        finally:
            browser.close()


@pytest.mark.slow
def test_a_panel_address_that_cannot_be_served_is_one_line_and_exit_2() -> None:
    """``--panel`` on a port in use, or on a host that does not resolve: one line naming the address,
    exit 2, and the simulator never starts (nothing on stdout)."""
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        for address, why in ((f"127.0.0.1:{port}", "the port is in use"),
                             ("no-such-host.invalid:8080", "no such host"), ("8080x", "numeric port")):
            r = xac1("sim", "--pty", "--panel", address, timeout=30)
            assert (r.returncode, r.stdout) == (2, ""), r.stderr
            assert len(r.stderr.splitlines()) == 1 and why in r.stderr, r.stderr


@pytest.mark.slow
def test_deviation_list_needs_no_transport() -> None:
    """Issue 40 item 10: ``xac1 sim --deviation list`` lists every deviation, as --help says, with no
    --pty or --tcp, then every robustness fault, marked as one the conformance suite does not check;
    without the list, a transport is still required (exit 2, one line)."""
    r = xac1("sim", "--deviation", "list", timeout=30)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert [line.split()[0] for line in lines] == [*DEVIATIONS, *ROBUSTNESS]
    assert [line.split()[0] for line in lines if line.endswith(f"[{ROBUSTNESS_MARK}]")] == list(ROBUSTNESS)
    r = xac1("sim", "--time-scale", "0", timeout=30)
    assert r.returncode == 2
    assert r.stderr.strip() == "xac1 sim: error: one of the arguments --pty --tcp is required"
