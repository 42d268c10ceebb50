"""``xac1 decode``: captures made by the real tools decode to the same frames and violations; the
gallery decodes with no options; broken files give located messages and partial results, never a
traceback (issue: offline decode; docs/protocol.md "Violation codes")."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from conftest import CAPTURES, gallery, xac1

from sniffer.analyzer import analyze
from sniffer.io.registry import Capture, detect

# the live session: the gallery's, without the step that waits for no-answer (kept fast)
LIVE = [step for step in gallery.SESSION if step[1] is not None]
LIVE_VIOLATIONS = sorted(v for v in gallery.EXPECTED_VIOLATIONS if v != "no-answer")


def conversation(paths: list[Path], fmt: str | None = None,
                 **kw) -> tuple[list[tuple[str, bytes]], list[str]]:
    """(dir, raw) of every frame/junk record and the sorted distinct violation codes."""
    names = [str(p) for p in paths]
    with Capture(names, fmt or detect(names).name, **kw) as cap:
        records = analyze(list(cap))
    frames = [(r.dir, r.raw) for r in records if r.type in ("frame", "junk")]
    return frames, sorted({v for r in records for v in r.violations})


def expected_frames(session) -> list[tuple[str, bytes]]:
    out = []
    for command, answer, _ in session:
        out.append(("host", command))
        if answer is not None:
            out.append(("device", answer))
    return out


@pytest.mark.slow
@pytest.mark.requires_tool("socat")
@pytest.mark.parametrize("options", [["-x", "-v"], ["-x"], ["-v"]], ids=["x-v", "x", "v"])
def test_live_socat_capture_decodes_to_the_session(tmp_path: Path, options: list[str]) -> None:
    """The scripted session through real socat (each dump style) decodes to its frames and violations."""
    log = tmp_path / "socat.log"
    gallery.capture_socat(log, options, LIVE, scale=0.2)
    frames, violations = conversation([log])
    assert frames == expected_frames(LIVE)
    assert violations == LIVE_VIOLATIONS


@pytest.mark.slow
@pytest.mark.requires_tool("jpnevulator")
def test_live_jpnevulator_and_spy_agree_with_socat(tmp_path: Path) -> None:
    """The same session through jpnevulator (two ttys, aliases; then --ascii --byte-count --width) and
    pyserial spy:// gives the same frames and the same violations."""
    results = []
    j1, j2, s = tmp_path / "j1.txt", tmp_path / "j2.txt", tmp_path / "spy.log"
    gallery.capture_jpnevulator(j1, [], session=LIVE, scale=0.2)
    gallery.capture_jpnevulator(j2, ["--ascii", "--byte-count", "--width", "5"], names=("", ""),
                                session=LIVE, scale=0.2)
    gallery.capture_spy(s, LIVE, scale=0.2)
    for path in (j1, j2, s):
        results.append(conversation([path]))
    for frames, violations in results:
        assert frames == expected_frames(LIVE)
        assert violations == LIVE_VIOLATIONS


@pytest.mark.slow  # starts a process
@pytest.mark.requires_tool("sigrok-cli")
def test_sigrok_cli_annotations_of_a_synthesized_waveform(tmp_path: Path) -> None:
    """sigrok-cli's UART decoder (two instances) on a synthesized 9600 8N1 waveform: the frames,
    violations and times of the session, with or without --samplerate."""
    out = tmp_path / "sigrok.txt"
    gallery.capture_sigrok(out, samplerate=48000)
    for kw in ({"samplerate": 48000.0}, {}):
        frames, violations = conversation([out], **kw)
        assert frames == expected_frames(gallery.SESSION)
        assert violations == sorted(gallery.EXPECTED_VIOLATIONS)


@pytest.mark.slow  # starts a process
@pytest.mark.requires_tool("tshark", "editcap")
def test_pcapng_written_is_read_by_tshark_and_editcap_pcap_decodes(tmp_path: Path) -> None:
    """Our pcapng is an RTAC serial capture for tshark; editcap's pcap of it decodes to the session."""
    ng, pc = tmp_path / "s.pcapng", tmp_path / "s.pcap"
    gallery.write_pcapng(ng)
    shown = subprocess.run(["tshark", "-r", str(ng), "-T", "fields", "-e", "rtacser.eventtype"],
                           capture_output=True, text=True, timeout=60, check=True).stdout.split()
    assert shown[:2] == ["0x01", "0x02"]
    subprocess.run(["editcap", "-F", "pcap", str(ng), str(pc)], check=True, timeout=60)
    for path in (ng, pc):
        frames, violations = conversation([path])
        assert frames == expected_frames(gallery.SESSION)
        assert violations == sorted(gallery.EXPECTED_VIOLATIONS)


GALLERY = sorted(p.name for p in CAPTURES.iterdir()
                 if p.is_file() and p.suffix != ".py" and p.name != "README.md")


@pytest.mark.slow
@pytest.mark.parametrize("name", GALLERY)
def test_every_gallery_file_decodes_with_no_options(name: str) -> None:
    """``xac1 decode captures/<any>`` works as a new user types it: the sloppy host's and the faulty
    device's violations are all found (untimed captures pair by order, so no-answer may show as
    overlapping-command)."""
    result = xac1("decode", f"captures/{name}", "--format", "jsonl")
    assert result.returncode == 1, result.stderr
    assert "Traceback" not in result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    found = set(lines[-1]["violations"])
    assert lines[-1]["type"] == "summary"
    wanted = set(gallery.EXPECTED_VIOLATIONS) - {"no-answer"}
    assert wanted <= found, result.stderr
    assert lines[-1]["frames"] == {"host": 9, "device": 8}


def test_gallery_readme_names_every_file() -> None:
    """captures/README.md says how each gallery file was made."""
    text = (CAPTURES / "README.md").read_text()
    assert all(f"`{name}`" in text for name in GALLERY)


@pytest.mark.slow
def test_truncated_and_corrupt_files_give_partial_results(tmp_path: Path) -> None:
    """A cut pcapng and a socat log with garbage lines: messages with file and place, the frames
    before the damage, the unread amount, exit status 1, no traceback."""
    cut = tmp_path / "cut.pcapng"
    data = (CAPTURES / "session.pcapng").read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    result = xac1("decode", str(cut))
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert "file ends inside block" in result.stderr and "could not read" in result.stderr
    assert "0RV100" in result.stdout.replace("\\r\\n", "")
    bad = tmp_path / "bad.log"
    lines = (CAPTURES / "socat-xv.log").read_text().splitlines()
    lines[4] = "@@@ corrupted @@@"
    bad.write_text("\n".join(lines) + "\n")
    result = xac1("decode", str(bad), "--input-format", "socat", "--format", "summary")
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert f"{bad}:5:" in result.stderr


@pytest.mark.slow
def test_cli_errors_are_one_line_messages(tmp_path: Path) -> None:
    """Missing file, unknown content, a --host-is the format does not name: exit 2 and a message."""
    junk = tmp_path / "x.txt"
    junk.write_text("nothing to see\n")
    for args, words in ((["nope.log"], "no such file"), ([str(junk)], "considered"),
                        (["captures/socat-x.log", "--host-is", "TX"], "'>' and '<'")):
        result = xac1("decode", *args)
        assert result.returncode == 2 and words in result.stderr and "Traceback" not in result.stderr


@pytest.mark.slow
def test_filters_and_host_override() -> None:
    """--only-violations shows only faulty records, --header 0WP keeps that command and its answer,
    --host-is '<' swaps the sides (then every command is an answer out of place)."""
    only = xac1("decode", "captures/socat-xv.log", "--format", "jsonl", "--only-violations")
    records = [json.loads(line) for line in only.stdout.splitlines()][:-1]
    assert records and all(r["violations"] for r in records)
    wp = xac1("decode", "captures/socat-xv.log", "--format", "jsonl", "--header", "0WP")
    records = [json.loads(line) for line in wp.stdout.splitlines()][:-1]
    assert [(r["dir"], r["header"]) for r in records] == [("host", "0WP"), ("device", "0WP")]
    swapped = xac1("decode", "captures/socat-xv.log", "--format", "jsonl", "--host-is", "<")
    summary = json.loads(swapped.stdout.splitlines()[-1])
    assert "unsolicited-answer" in summary["violations"]


@pytest.mark.slow
def test_decoded_jsonl_decodes_again_to_the_same(tmp_path: Path) -> None:
    """Our decoded output is itself a capture: decoding it again gives the same records."""
    first = xac1("decode", "captures/socat-xv.log", "--format", "jsonl")
    out = tmp_path / "decoded.jsonl"
    out.write_text(first.stdout)
    second = xac1("decode", str(out), "--format", "jsonl")
    assert [json.loads(line) for line in second.stdout.splitlines()] == \
        [json.loads(line) for line in first.stdout.splitlines()]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["saleae-ascii-host.csv", "saleae-logic2-glitch.csv"])
def test_saleae_framing_error_is_a_line_error_on_its_frame(name: str) -> None:
    """Saleae files with a framing error (ASCII radix analyzer export; Logic 2 table): the flagged byte
    is read, the frame holding it (the device's 0WP echo) carries it under ``line_errors``, the
    summary counts one such record, and the session decodes as in every other format."""
    result = xac1("decode", f"captures/{name}", "--format", "jsonl")
    assert result.returncode == 1 and "Traceback" not in result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    flagged = [r for r in lines[:-1] if r.get("line_errors")]
    assert [(r["dir"], r["header"], bytes.fromhex(r["raw"])) for r in flagged] == \
        [("device", "0WP", b"0WP19302012344\r\n")]
    assert "framing error" in flagged[0]["line_errors"][0]
    assert lines[-1]["line_errors"] == 1 and lines[-1]["frames"] == {"host": 9, "device": 8}
    frames, violations = conversation([CAPTURES / name] + ([CAPTURES / "saleae-ascii-device.csv"]
                                                          if "ascii" in name else []))
    assert frames == expected_frames(gallery.SESSION)
    assert violations == sorted(gallery.EXPECTED_VIOLATIONS)


@pytest.mark.slow
def test_untimed_capture_says_what_order_cannot_tell() -> None:
    """interceptty without -T has no time: the unanswered 0RV shows as overlapping-command on the next
    0RV, with a detail saying it may as well be a no-answer (docs/captures.md)."""
    result = xac1("decode", "captures/interceptty.log", "--format", "jsonl")
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    overlap = [r for r in lines[:-1] if "overlapping-command" in r["violations"]]
    assert len(overlap) == 1 and overlap[0]["header"] == "0RV"
    assert "no time" in overlap[0]["details"][-1] and "no-answer" in overlap[0]["details"][-1]
    timed = xac1("decode", "captures/interceptty-T.log", "--format", "summary")
    assert "no-answer" in timed.stdout and "overlapping-command" not in timed.stdout
