"""The XA-C1 decoder in the real sigrok-cli (Debian's, libsigrokdecode 0.5), installed by ``xac1 sigrok
install`` into a temporary XDG_DATA_HOME: logic captures of simulator conversations (two UART lines at
9600 8N1, as VCD) decoded frame by frame, compared with ``xac1 decode``'s records of the same bytes (the
UART decoder's export of the same capture): frames, meanings, fields, frame-level codes, UART errors."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from sigrok_logic import (
    LEAD_S,
    TIMESCALE_HZ,
    UART,
    Annotation,
    Capture,
    annotations,
    converse,
    sigrok,
    write_vcd,
)

from xac1_proto import spec
from xac1_proto.sim import LineFaults, SimConfig

pytestmark = [pytest.mark.slow, pytest.mark.requires_tool("sigrok-cli")]  # sigrok-cli, xac1 processes

CLEAN = [
    (0.00, b"0RV\r\n"), (0.05, b"0MP0\r\n"), (0.10, b"0WP19302012345\r\n"), (0.15, b"0RP1\r\n"),
    (0.20, b"0MP1\r\n"), (0.25, b"0RC\r\n"), (0.30, b"0WS32\r\n"), (0.35, b"0RS\r\n"),
    (0.40, b"0MV0F3001388\r\n"), (0.45, b"0CM1\r\n"), (0.50, b"0WC2\r\n"), (0.55, b"0%C\r\n"),
]
# A sloppy host (docs/protocol.md "Violation codes"): a letter O, lower case in a header and in a field,
# a short frame without its 2, a field out of range, a bare LF, an unknown command, junk; and, for the
# engine only, alarms ignored and commands overlapping.
SLOPPY = [
    (0.00, b"0RV\r\n"), (0.05, b"ORV\r\n"), (0.10, b"0%C\r\n"), (0.15, b"0rv\r\n"), (0.20, b"0%C\r\n"),
    (0.25, b"0WP1930201abcd\r\n"), (0.30, b"0WS1\r\n"), (0.35, b"0RP0\r\n"), (0.40, b"0%C\r\n"),
    (0.45, b"0RV\n"), (0.50, b"0%C\r\n"), (0.55, b"0QQ\r\n"), (0.60, b"hello\r\n"), (0.65, b"0%C\r\n"),
    (0.70, b"0RV\r\n0RS\r\n"), (0.80, b"0CM7\r\n"), (0.85, b"0%C\r\n"), (0.90, b"0RP3\r\n"),
]
CONVERSATION_CODES = {v.code for v in spec.VIOLATION_SPECS if v.duty != spec.SENDER}


def sessions() -> dict[str, Capture]:
    return {
        "clean": converse(CLEAN),
        "sloppy-host": converse(SLOPPY),
        "faulty-device": converse(CLEAN, SimConfig(time_scale=0,
                                                   deviations=frozenset({"no-2", "echo-differs"}))),
        "garbling-device": converse(CLEAN + [(0.60 + 0.05 * k, b"0RP1\r\n") for k in range(8)],
                                    SimConfig(time_scale=0, deviations=frozenset({"wrong-length"}),
                                              faults=LineFaults(corrupt=0.03, seed=11))),
        # alarms the device raises: one the vendor lists with no meaning (reserved-alarm), an emergency stop
        "alarming-device": converse(CLEAN[:6], alarms={1: 0x03, 3: 0x0B, 5: 0x0E}),
        # bytes damaged on the wire: a host command's third byte, an answer's first and fifth bytes
        "uart-framing-error": converse([*CLEAN[:2], (0.10, CLEAN[2][1], frozenset({2})), *CLEAN[3:]],
                                       device_bad={3: frozenset({0, 4}), 6: frozenset({1})}),
        # a host frame paused for 2 s (reassembled), an answer paused for 1.5 s (quiet past the idle
        # flush: junk) and one paused for 0.4 s (reassembled)
        "split-frames": converse([(0.00, b"0WP1930"), (2.00, b"2012345\r\n"), (2.10, b"0RP1\r\n"),
                                  (4.00, b"0RV\r\n"), (4.10, b"0RC\r\n")],
                                 device_split={1: 1.5, 2: 0.4}),
    }


SESSIONS = sessions()


@pytest.fixture(scope="module")
def env(tmp_path_factory) -> dict[str, str]:
    """An environment whose XDG_DATA_HOME got the decoder by one ``xac1 sigrok install``."""
    root = tmp_path_factory.mktemp("sigrok-home")
    env = {**os.environ, "HOME": str(root / "home"), "XDG_DATA_HOME": str(root / "data")}
    done = xac1("sigrok", "install", env=env)
    assert done.returncode == 0, done.stderr
    return env


def xac1(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "xac1_proto", *args], capture_output=True, text=True,
                          timeout=120, env=env)


# ---- what the decoder showed, and what xac1 decode says of the same bytes ----

@dataclass
class Item:
    """One frame or junk run: as the decoder annotated it, or as xac1 decode's record has it."""

    side: str
    raw: bytes
    what: str  # the frame's meaning, or the junk's reason
    fields: str | None = None
    codes: list[str] = field(default_factory=list)
    uart: list[str] = field(default_factory=list)
    span: tuple[int, int] = (0, 0)


_FRAME = re.compile(r"(\S+) (command|answer): (.*)")
_JUNK = re.compile(r"(\S+) (host|device) junk \(([\w-]+)\)")
_FIELDS = re.compile(r"\w+=\S+(?: \w+=\S+)*")


def unescape(text: str) -> bytes:
    out = bytearray()
    k = 0
    while k < len(text):
        c = text[k]
        if c != "\\":
            out.append(ord(c))
            k += 1
            continue
        nxt = text[k + 1]
        if nxt == "x":
            out.append(int(text[k + 2:k + 4], 16))
            k += 4
            continue
        out.append({"r": 13, "n": 10, "\\": 92}[nxt])
        k += 2
    return bytes(out)


def decoded(anns: list[Annotation]) -> list[Item]:
    """The decoder's annotations, one Item a frame or junk run (its other annotations share its span)."""
    items: list[Item] = []
    for a in anns:
        if m := _FRAME.fullmatch(a.text):
            raw = unescape(m.group(1))
            side = spec.HOST_SIDE if m.group(2) == spec.COMMAND else spec.DEVICE_SIDE
            items.append(Item(side, raw if raw.endswith(b"\n") else raw + spec.TERMINATOR, m.group(3),
                              span=(a.ss, a.es)))
            continue
        if m := _JUNK.fullmatch(a.text):
            items.append(Item(m.group(2), unescape(m.group(1)), m.group(3), span=(a.ss, a.es)))
            continue
        item = items[-1]
        assert (a.ss, a.es) == item.span, (a, item)
        if _FIELDS.fullmatch(a.text):
            assert item.fields is None
            item.fields = a.text
        elif a.text.startswith("UART "):
            item.uart.append(a.text)
        else:
            assert a.text in spec.VIOLATION_TABLE, a.text
            item.codes.append(a.text)
    for item in items:  # junk always carries its code
        if _JUNK_REASONS.get(item.what):
            assert item.codes[:1] == ["garbage"]
            item.codes = item.codes[1:]
    return items


_JUNK_REASONS = {"no-frame-start": True, "truncated": True, "overflow": True, "flushed": True}


def _meaning(header: str | None, role: str, fields: dict | None) -> str:
    """The meaning a frame of this header has in spec.py's tables (the alarm's name for 0%%)."""
    if header is None:
        return f"unknown {role}"
    if header == spec.ALARM_HEADER and fields:
        return f"alarm {spec.FIELDS['code'].show(fields['code'])}: {spec.alarm_meaning(fields['code'])}"
    return spec.SPECS[(header, role)].meaning  # type: ignore[index]


def _fields_text(fields: dict | None) -> str | None:
    if not fields:
        return None
    return " ".join(f"{spec.FIELDS[n].label}={v if spec.FIELDS[n].text else spec.FIELDS[n].show(v)}"
                    for n, v in fields.items())


def expected(records: list[dict]) -> list[Item]:
    """xac1 decode's frame and junk records as Items (frame-level codes only; each kind of UART error once,
    where a record lists it for each byte it hit)."""
    out = []
    for r in records:
        if r["type"] in ("frame", "junk"):
            r["line_errors"] = list(dict.fromkeys(r.get("line_errors", [])))
        if r["type"] == "frame":
            role = spec.COMMAND if r["dir"] == spec.HOST_SIDE else spec.ANSWER
            codes = [c for c in r["violations"] if c not in CONVERSATION_CODES]
            out.append(Item(r["dir"], bytes.fromhex(r["raw"]), _meaning(r["header"], role, r["fields"]),
                            _fields_text(r["fields"]), codes, r.get("line_errors", [])))
        elif r["type"] == "junk":
            out.append(Item(r["dir"], bytes.fromhex(r["raw"]), r["reason"], None, [],
                            r.get("line_errors", [])))
    return out


def decode_records(vcd: Path, tmp: Path, env: dict[str, str]) -> list[dict]:
    """``xac1 decode`` of the UART decoder's export of ``vcd`` (one instance a line: host first)."""
    export = tmp / f"{vcd.stem}.sigrok"
    done = sigrok("-i", str(vcd), "-P", f"uart:baudrate={spec.BAUD}:rx=host", "-P",
                  f"uart:baudrate={spec.BAUD}:rx=device", "-A", "uart=rx-data:rx-warnings",
                  "--protocol-decoder-samplenum", env=env)
    assert done.returncode == 0, done.stderr
    export.write_text(done.stdout, encoding="utf-8")
    done = xac1("decode", "-I", "sigrok", "--samplerate", str(TIMESCALE_HZ), "-f", "jsonl", str(export),
                env=env)
    assert done.returncode in (0, 1), done.stderr
    import json

    return [json.loads(line) for line in done.stdout.splitlines()]


def by_side(items: list[Item], side: str) -> list[Item]:
    return [i for i in items if i.side == side]


def _strip_span(item: Item) -> Item:
    return Item(item.side, item.raw, item.what, item.fields, item.codes, item.uart)


@pytest.mark.parametrize("name", list(SESSIONS))
def test_annotations_equal_decode_records_frame_by_frame(name, env, tmp_path):
    """Every frame and junk run of each line, in order: the same bytes, meaning, fields, frame-level
    violation codes and UART errors as ``xac1 decode``'s records of the same capture; no conversation
    code; each annotation spans the frame's samples, first start bit to last stop bit."""
    cap = SESSIONS[name]
    vcd = write_vcd(tmp_path / f"{name}.vcd", cap)
    got = decoded(annotations(vcd, env, "xac1"))
    want = expected(decode_records(vcd, tmp_path, env))
    assert want, "xac1 decode found nothing"
    for side in (spec.HOST_SIDE, spec.DEVICE_SIDE):
        ours, theirs = by_side(got, side), by_side(want, side)
        assert [_strip_span(i) for i in ours] == theirs, side
        line = getattr(cap, side)
        at = 0
        for item in ours:
            first, last = line.bytes_[at], line.bytes_[at + len(item.raw) - 1]
            at += len(item.raw)
            start = (LEAD_S + first[0]) * TIMESCALE_HZ
            end = (LEAD_S + last[0]) * TIMESCALE_HZ + spec.BYTE_TIME_S * TIMESCALE_HZ
            assert abs(item.span[0] - start) <= 2 and abs(item.span[1] - end) <= 3, (item, start, end)
        assert at == len(line.bytes_), "every byte of the line is in a frame or a junk run"


def test_sessions_hold_what_their_names_say(env, tmp_path):
    """The captures are what the comparison needs: the sloppy host's every frame-level fault, a faulty
    device's, a reserved alarm, UART framing errors on both lines, a junk run left by an answer's long
    pause."""
    seen: dict[str, Counter[str]] = {}
    for name in ("sloppy-host", "faulty-device", "garbling-device", "alarming-device", "uart-framing-error",
                 "split-frames"):
        vcd = write_vcd(tmp_path / f"{name}.vcd", SESSIONS[name])
        records = decode_records(vcd, tmp_path, env)
        seen[name] = Counter(c for r in records for c in r.get("violations", []))
        seen[name].update(f"line:{r['dir']}" for r in records
                          if r["type"] != "summary" and r.get("line_errors"))
        seen[name].update(f"reason:{r['reason']}" for r in records if r["type"] == "junk")
    assert {"letter-o", "lowercase-hex", "bad-length", "missing-2", "field-range", "bad-terminator",
            "unknown-command", "garbage", "alarm-ignored", "overlapping-command"} <= set(seen["sloppy-host"])
    assert {"missing-2", "bad-length", "echo-mismatch"} <= set(seen["faulty-device"])
    assert {"bad-length", "garbage"} <= set(seen["garbling-device"])
    assert "reserved-alarm" in seen["alarming-device"]
    assert {"line:host", "line:device"} <= set(seen["uart-framing-error"])
    assert "reason:flushed" in seen["split-frames"]


def test_done_when_sloppy_host_names_every_frame_level_violation_and_no_other(env, tmp_path):
    """Issue 26's done-when: after one ``xac1 sigrok install``, ``sigrok-cli -i CAPTURE -P
    uart:baudrate=9600:rx=device:tx=host,xac1 -A xac1`` on a sloppy-host session names every frame-level
    violation the session holds (as many times as xac1 decode finds it) and no other code."""
    vcd = write_vcd(tmp_path / "sloppy.vcd", SESSIONS["sloppy-host"])
    done = sigrok("-i", str(vcd), "-P", "uart:baudrate=9600:rx=device:tx=host,xac1", "-A", "xac1", env=env)
    assert done.returncode == 0 and not done.stderr, done.stderr
    shown = [line.split(": ", 1)[1] for line in done.stdout.splitlines()]
    named = Counter(text for text in shown if text in spec.VIOLATION_TABLE)
    records = decode_records(vcd, tmp_path, env)
    held = Counter(c for r in records if r["type"] in ("frame", "junk") for c in r["violations"]
                   if c not in CONVERSATION_CODES)
    assert named == held
    assert {"alarm-ignored", "overlapping-command"} <= {c for r in records for c in r["violations"]}
    assert not CONVERSATION_CODES & set(shown)
    assert "0RP3 command: read movement data of point N" in shown and "N=3" in shown


PROBE = """\"\"\"A test decoder stacked on xac1: each packet of its Python output as an annotation.\"\"\"
import sigrokdecode as srd


class Decoder(srd.Decoder):
    api_version = 3
    id = "xac1probe"
    name = "XA-C1 probe"
    longname = "XA-C1 output probe (tests)"
    desc = "Shows what the XA-C1 decoder passes on."
    license = "mit"
    inputs = ["xac1"]
    outputs = []
    annotations = (("packet", "Packet"),)

    def reset(self):
        pass

    def start(self):
        self.out_ann = self.register(srd.OUTPUT_ANN)

    def decode(self, ss, es, data):
        kind, side, fields = data
        self.put(ss, es, self.out_ann, [0, [repr((kind, side, sorted(fields.items())))]])
"""


@pytest.mark.parametrize("name", ["sloppy-host", "uart-framing-error"])
def test_python_output_feeds_a_stacked_decoder(name, env, tmp_path):
    """A decoder stacked on xac1 gets one packet a frame or junk run, over its samples: the bytes, role,
    header, fields, frame-level codes and UART errors that xac1 decode's records hold."""
    probe = Path(env["XDG_DATA_HOME"]) / "libsigrokdecode" / "decoders" / "xac1probe"
    probe.mkdir(exist_ok=True)
    (probe / "__init__.py").write_text(PROBE.split("import", 1)[0] + "from .pd import Decoder  # noqa\n")
    (probe / "pd.py").write_text(PROBE)
    vcd = write_vcd(tmp_path / f"{name}.vcd", SESSIONS[name])
    got = {}
    for a in annotations(vcd, env, "xac1", "xac1probe"):
        kind, side, items = ast.literal_eval(a.text)
        got.setdefault(side, []).append((kind, dict(items)))
    want: dict[str, list] = {}
    for r in decode_records(vcd, tmp_path, env):
        if r["type"] == "frame":
            role = spec.COMMAND if r["dir"] == spec.HOST_SIDE else spec.ANSWER
            want.setdefault(r["dir"], []).append(("FRAME", {
                "raw": bytes.fromhex(r["raw"]), "role": role, "header": r["header"],
                "meaning": _meaning(r["header"], role, r["fields"]), "fields": r["fields"],
                "violations": [c for c in r["violations"] if c not in CONVERSATION_CODES],
                "uart_errors": list(dict.fromkeys(r.get("line_errors", [])))}))
        elif r["type"] == "junk":
            want.setdefault(r["dir"], []).append(("JUNK", {
                "raw": bytes.fromhex(r["raw"]), "reason": r["reason"], "violations": ["garbage"],
                "uart_errors": list(dict.fromkeys(r.get("line_errors", [])))}))
    assert got == want


def test_host_option_picks_the_line(env, tmp_path):
    """``host=rx``: with the lines wired the other way round the decoder shows the same annotations."""
    vcd = write_vcd(tmp_path / "sloppy.vcd", SESSIONS["sloppy-host"])
    default = sigrok("-i", str(vcd), "-P", f"{UART},xac1", "-A", "xac1", env=env)
    swapped = sigrok("-i", str(vcd), "-P", "uart:baudrate=9600:rx=host:tx=device,xac1:host=rx", "-A", "xac1",
                     env=env)
    assert default.returncode == swapped.returncode == 0, swapped.stderr
    assert default.stdout == swapped.stdout and "command: " in default.stdout


def test_listed_with_its_description(env):
    """sigrok-cli lists the installed decoder; its description says xac1 decode judges the conversation."""
    done = sigrok("-L", env=env)
    assert re.search(r"^\s+xac1\s+SUS XA-C1 actuator controller$", done.stdout, re.M), done.stdout
    info = sigrok("-P", "xac1", "--show", env=env)
    assert "xac1 decode" in info.stdout and "host" in info.stdout, info.stdout


def test_install_into_home_without_xdg_data_home(tmp_path):
    """Without XDG_DATA_HOME the decoder goes to ~/.local/share/libsigrokdecode/decoders, where sigrok-cli
    finds it; a second install changes nothing; --uninstall takes it away and sigrok-cli no longer
    lists it."""
    env = {k: v for k, v in os.environ.items() if k != "XDG_DATA_HOME"}
    env["HOME"] = str(tmp_path)
    folder = tmp_path / ".local/share/libsigrokdecode/decoders/xac1"
    assert xac1("sigrok", "install", env=env).returncode == 0
    assert re.search(r"^\s+xac1\s", sigrok("-L", env=env).stdout, re.M)
    again = xac1("sigrok", "install", env=env)
    assert again.returncode == 0 and f"{folder} (already up to date)" in again.stdout
    assert f"xac1:     {folder}" in xac1("sigrok", "path", env=env).stdout
    assert xac1("sigrok", "install", "--uninstall", env=env).returncode == 0
    assert not folder.exists()
    assert not re.search(r"^\s+xac1\s", sigrok("-L", env=env).stdout, re.M)


def test_install_into_a_read_only_folder(tmp_path):
    """A decoders folder that cannot be written: exit 1 and a message naming it, no traceback, nothing
    written. Root writes into read-only folders, so as root the folder is made immutable (chattr +i)."""
    data = tmp_path / "data"
    decoders = data / "libsigrokdecode" / "decoders"
    decoders.mkdir(parents=True)
    env = {**os.environ, "HOME": str(tmp_path), "XDG_DATA_HOME": str(data)}
    decoders.chmod(0o555)
    immutable = os.geteuid() == 0
    if immutable:
        made = subprocess.run(["chattr", "+i", str(decoders)], capture_output=True, text=True)
        assert made.returncode == 0, f"chattr +i (e2fsprogs) is needed when the tests run as root: {made}"
    try:
        done = xac1("sigrok", "install", env=env)
        assert done.returncode == 1 and "Traceback" not in done.stderr
        assert done.stderr.startswith(f"xac1 sigrok: error: cannot write in {decoders / 'xac1'}") or \
            done.stderr.startswith(f"xac1 sigrok: error: cannot write in {decoders}"), done.stderr
        assert list(decoders.iterdir()) == []
    finally:
        if immutable:
            subprocess.run(["chattr", "-i", str(decoders)], check=True)
        decoders.chmod(0o755)


def test_nine_data_bits_is_one_annotation_saying_the_setting_is_wrong(env, tmp_path):
    """The UART decoder set to 9 data bits hands values above a byte: the decoder says once that the
    setting is wrong (XA-C1 is 8N1) and raises nothing (was: ``ValueError: bytes must be in range(0,
    256)`` on every byte)."""
    vcd = write_vcd(tmp_path / "clean.vcd", SESSIONS["clean"])
    done = sigrok("-i", str(vcd), "-P", f"{UART}:data_bits=9,xac1", "-A", "xac1", env=env)
    assert "Error" not in done.stderr and "range(0, 256)" not in done.stderr + done.stdout, done.stderr
    said = [line for line in done.stdout.splitlines() if "UART decoder set wrong" in line]
    assert len(said) == 1 and "data_bits=8" in said[0], done.stdout[-2000:]
