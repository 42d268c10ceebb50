"""The session report without a browser: the streaming aggregator (bounded, and faithful to the records
it is fed), the page's embedded data, ``--report`` on ``xac1 decode`` (empty capture, unwritable path,
plotly missing) and a long capture in bounded memory (issue 17)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from peak_rss import run_measuring_peak_rss
from strategies import frames

from sniffer.analyzer import Analyzer
from sniffer.records import FrameRecord, TimeoutRecord
from sniffer.report import Limits, SessionAggregator, SessionReport
from sniffer.report.aggregate import LogHistogram, TimeBins
from xac1_proto import spec
from xac1_proto.chunk import Chunk

ROOT = Path(__file__).resolve().parent.parent
CAPTURES = ROOT / "captures"
XAC1 = [sys.executable, "-m", "xac1_proto"]
H, D = "host", "device"


def analyze(chunks: list[Chunk]) -> list:
    analyzer = Analyzer()
    out = []
    for c in chunks:
        out += analyzer.feed(c)
    return out + analyzer.close()


def embedded(page: str, element: str) -> dict:
    """The JSON the page embeds in ``<script type="application/json" id=element>``."""
    match = re.search(rf'<script type="application/json" id="{element}">(.*?)</script>', page, re.S)
    assert match, f"no {element} in the page"
    return json.loads(match.group(1))


def run(*args: str, cwd: Path = ROOT, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*XAC1, *args], capture_output=True, text=True, timeout=300, cwd=cwd, **kw)


# ---- the aggregator ----

@settings(max_examples=budget(40), deadline=None)
@given(st.lists(st.tuples(st.sampled_from([H, D]),
                          st.one_of(st.binary(max_size=20), frames().map(lambda f: f.to_bytes())),
                          st.floats(0, 2.0)), max_size=40),
       st.booleans(), st.integers(1, 6))
def test_aggregator_counts_every_record_and_keeps_within_limits(items, timed, cap):
    """Whatever the traffic, the aggregator counts every record, every violation code (each mark on the
    side ``spec.VIOLATION_TABLE[code].side(dir)`` names) and every answered command, exactly as the
    records say; it keeps whole no more records than its limits allow and its bins stay under their
    limit (docs/protocol.md "Violation codes": the report judges nothing itself)."""
    t, chunks = 0.0, []
    for d, data, dt in items:
        t += dt
        chunks.append(Chunk(t if timed else None, d, data))
    records = analyze(chunks)
    limits = Limits(records=cap, violation_records=cap, bins=4, points=cap, alarms=cap)
    agg = SessionAggregator(limits=limits)
    for r in records:
        agg.add(r)
    agg.finish()
    assert agg.total_records == len(records)
    assert agg.mark_count == sum(len(r.violations) for r in records)
    sides: dict[tuple[str, str], int] = {}
    for r in records:
        for code in r.violations:
            key = (code, spec.VIOLATION_TABLE[code].side(r.dir))
            sides[key] = sides.get(key, 0) + 1
    assert dict(agg.sides) == sides
    assert agg.exchange_count == sum(1 for r in records if isinstance(r, FrameRecord) and r.dir == D
                                     and r.reply_to is not None)
    assert len(agg.records) <= 2 * cap and len(agg.records) + agg.dropped_records == len(records)
    assert len(agg.marks) == sum(len(rec["violations"]) for rec in agg.records)
    assert len(agg.bins.bins) <= 4 and len(agg.latency_points.items) <= cap
    totals = {k: sum(agg.bins.series(k)[1]) for k in agg.bins.keys()}  # noqa: SIM118
    assert sum(v for k, v in totals.items() if k.startswith("violation:")) == agg.mark_count
    assert agg.timed == (timed or not records)
    json.dumps(agg.records, allow_nan=False)


@given(st.floats(1e-4, 1e6))
def test_log_histogram_bucket_holds_the_value(value):
    """A latency falls in the bucket named for it: two significant digits, at most 90 buckets a decade."""
    low = LogHistogram.bucket(value)
    assert low <= value * (1 + 1e-9) and value < low + LogHistogram.step(value) * (1 + 1e-9)


@given(st.lists(st.floats(0, 1e5), max_size=300), st.integers(2, 20))
def test_time_bins_coarsen_without_losing_counts(xs, limit):
    """Past their limit the bins double their width: fewer bins, the same counts and maxima."""
    bins = TimeBins(limit)
    for x in xs:
        bins.add(x, "k", x)
    assert len(bins.bins) <= limit
    _, counts, _, tops = bins.series("k")
    assert sum(counts) == len(xs)
    assert (max(tops) if tops else None) == (max(xs) if xs else None)


def test_alarm_history_reaction_and_latch_from_the_gallery_session():
    """The gallery session (captures/README.md): alarm 01 answers the letter-O command, the host ignores
    it (sends 0RS), the device answers 0RS normally (latch-broken: the engine holds the latch), the reset
    answered 0%C00 ends it. The span is the engine's latch, never a model of the report's own."""
    from sniffer.io.registry import Capture

    agg = SessionAggregator()
    with Capture([str(CAPTURES / "socat-xv.log")], "socat") as capture:
        analyzer = Analyzer()
        for chunk in capture:
            agg.feed(analyzer, chunk)
        for r in analyzer.close():
            agg.add(r)
    agg.finish(analyzer.summary())
    [alarm] = agg.alarms
    assert (alarm.code, alarm.answered, alarm.reaction) == (spec.ALARM_COMM, "0RP", "0RS")
    assert alarm.ended == "reset (0%C answered)"
    assert alarm.latched_for is not None and 0.1 < alarm.latched_for < 1.0
    assert agg.exchange_count == 8 and agg.mark_count == 7
    assert {code for code, _ in agg.sides} == {"letter-o", "echo-mismatch", "alarm-ignored", "latch-broken",
                                               "bad-length", "bad-terminator", "no-answer"}


# ---- the command line ----

@pytest.mark.slow  # starts a process
def test_decode_report_matches_the_jsonl_records(tmp_path):
    """``xac1 decode FILE --report`` writes one self-contained page whose embedded data has one record per
    record of ``--format jsonl``, the same violations and the same summary tables."""
    out = tmp_path / "s.html"
    done = run("decode", "captures/socat-xv.log", "--format", "jsonl", "--report", str(out))
    assert done.returncode == 1, done.stderr
    assert f"report written to {out}" in done.stderr
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    records, summary = lines[:-1], lines[-1]
    page = out.read_text(encoding="utf-8")
    data = embedded(page, "session-data")
    assert [r["violations"] for r in data["records"]] == [r["violations"] for r in records]
    assert [r.get("i") for r in data["records"]] == [r.get("i") for r in records]
    assert data["counts"]["marks"] == sum(len(r["violations"]) for r in records)
    for code, count in summary["violations"].items():
        assert re.search(rf"<code>{code}</code></td><td class=\"num\">{count}</td>", page), code
    assert not re.search(r"<(script|link|img|iframe)\b[^>]*\b(src|href)=", page), "the page loads a resource"
    assert "Content-Security-Policy" in page and "default-src 'none'" in page
    assert os.stat(out).st_mode & 0o777 == 0o666 & ~_umask()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@pytest.mark.slow  # starts a process
def test_empty_capture_gives_a_report_that_says_so(tmp_path):
    """A capture with nothing in it (a zero-byte file, a recording with no chunk) still gets its report,
    which says so; the exit status stays 2 (nothing decoded)."""
    zero = tmp_path / "zero.log"
    zero.write_bytes(b"")
    recording = tmp_path / "nothing.jsonl"
    recording.write_text('{"type":"recording","version":1,"started":1714557600.0,"source":"test"}\n')
    for capture in (zero, recording):
        out = tmp_path / f"{capture.stem}.html"
        done = run("decode", str(capture), "--report", str(out))
        assert done.returncode == 2, done.stderr
        page = out.read_text(encoding="utf-8")
        assert "This capture holds no frames" in page and str(capture) in page
        assert "<script>" in page and "Plotly.newPlot" in page  # the page script, with nothing to plot


@pytest.mark.slow  # starts a process
@pytest.mark.parametrize("where", ["missing-folder/s.html", "a-folder", "locked/s.html"])
def test_unwritable_report_path_is_refused_before_any_work(tmp_path, where):
    """``--report`` to a path that cannot be written: a clear error naming it, exit 2, and no output at
    all (the capture is not decoded)."""
    (tmp_path / "a-folder").mkdir()
    (tmp_path / "locked").mkdir(mode=0o500)
    target = tmp_path / where
    if os.geteuid() == 0 and where.startswith("locked"):  # root writes anywhere a mode allows: sysfs refuses
        target = Path("/sys/xac1-session.html")
    done = run("decode", str(CAPTURES / "socat-xv.log"), "--report", str(target))
    assert done.returncode == 2
    assert done.stdout == ""
    assert re.search(rf"cannot write the report {re.escape(str(target))}: "
                     r"(no such folder|it is a directory|permission denied|Permission denied)", done.stderr)
    assert not target.is_file()


@pytest.mark.slow  # starts a process
def test_unwritable_report_path_stops_sniff_before_opening_taps(tmp_path):
    """``xac1 sniff --report`` to a folder that does not exist: exit 2 before any tap is opened (the taps
    named here do not exist either: the report's error comes first)."""
    done = run("sniff", "--host-tap", str(tmp_path / "no-tap-1"), "--device-tap", str(tmp_path / "no-tap-2"),
               "--report", str(tmp_path / "missing" / "s.html"))
    assert done.returncode == 2
    assert "cannot write the report" in done.stderr and "no-tap" not in done.stderr


_NO_PLOTLY = ("import sys; sys.modules['plotly'] = None; from xac1_proto.cli import main; "
              "sys.argv = ['xac1'] + sys.argv[1:]; sys.exit(main())")


@pytest.mark.slow  # starts a process
def test_without_plotly_decode_works_and_report_names_the_extra(tmp_path):
    """Without the ``report`` extra (plotly unimportable): ``xac1 decode`` works as before; ``--report``
    says which extra to install, exit 2, nothing decoded."""
    plain = subprocess.run([sys.executable, "-c", _NO_PLOTLY, "decode", "captures/socat-xv.log",
                            "--format", "summary"], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert plain.returncode == 1 and "latch-broken" in plain.stdout, plain.stderr
    asked = subprocess.run([sys.executable, "-c", _NO_PLOTLY, "decode", "captures/socat-xv.log",
                            "--report", str(tmp_path / "s.html")], capture_output=True, text=True, cwd=ROOT,
                           timeout=60)
    assert asked.returncode == 2 and asked.stdout == ""
    assert "pip install 'xac1-proto[report]'" in asked.stderr
    assert not (tmp_path / "s.html").exists()


def test_report_object_refuses_a_directory(tmp_path):
    """The session report refuses a directory as its output path, saying so."""
    with pytest.raises(ValueError, match="it is a directory"):
        SessionReport.open(tmp_path, [])


# ---- a large capture ----

MAX_REPORT_BYTES = 9_000_000  # docs/output.md: a report stays under 9 MB whatever the capture
MAX_RSS_MB = 200


def write_recording(path: Path, frames_wanted: int) -> None:
    """A recording of ``frames_wanted`` frames at 20 exchanges a second: reads of the version and the
    position, and every 1,000th exchange a letter-O command answered by alarm 01, reset next."""
    t = 1714557600.0
    with open(path, "w", encoding="ascii") as f:
        f.write(json.dumps({"type": "recording", "version": 1, "started": t, "source": "generated"}) + "\n")
        for k in range(frames_wanted // 2):
            if k % 1000 == 999:
                command, answer = b"ORP1\r\n", b"0%%01\r\n"
            elif k % 1000 == 0 and k:
                command, answer = b"0%C\r\n", b"0%C00\r\n"
            elif k % 3 == 0:
                command, answer = b"0RC\r\n", b"0RC00002001234\r\n"  # the axis stays put
            else:
                command, answer = b"0RV\r\n", b"0RV100\r\n"
            answered = t + 0.012 + (k % 7) * 0.001
            f.write(f'{{"type":"chunk","t":{t:.6f},"dir":"host","data":"{command.hex()}"}}\n')
            f.write(f'{{"type":"chunk","t":{answered:.6f},"dir":"device","data":"{answer.hex()}"}}\n')
            t += 0.05


# Two captures, both far past every limit (the 3,000 records kept whole, the 1,500 violations, the 2,000
# bins, the 5,000 points): the longer is four times the shorter, so what the report or the process keeps
# per frame would show as growth between them. A report whose size and memory do not grow from one to the
# other is bounded for any length (docs/output.md's 1,000,000 frames included) at a fifth of that decode.
SHORT_FRAMES, LONG_FRAMES = 60_000, 240_000
MAX_GROWTH_BYTES = 200_000  # the report of 4x the frames: its marks (one a 1,000 exchanges), no more
MAX_GROWTH_MB = 10  # peak RSS of 4x the frames over the shorter's: allocator noise, nothing per frame


def decode_with_report(folder: Path, frames_wanted: int) -> tuple[str, int, float]:
    """``xac1 decode --report`` of a generated recording of ``frames_wanted`` frames: the page, its size
    and the process's peak RSS in MB (exit 1: the letter-O commands are violations)."""
    capture, out = folder / f"{frames_wanted}.jsonl", folder / f"{frames_wanted}.html"
    write_recording(capture, frames_wanted)
    code, rss_mb = run_measuring_peak_rss([*XAC1, "decode", str(capture), "--format", "summary",
                                           "--report", str(out)], cwd=ROOT)
    assert code == 1, f"{frames_wanted} frames: exit {code}"
    return out.read_text(encoding="utf-8"), out.stat().st_size, rss_mb


@pytest.mark.slow
def test_long_capture_report_is_bounded(tmp_path):
    """A long capture decodes with ``--report`` in bounded memory into a bounded report: for 4x the
    frames (60,000 then 240,000, both past every limit) neither the report's size nor the peak RSS grows
    beyond noise, both stay under MAX_REPORT_BYTES and MAX_RSS_MB, and the longer report says it
    aggregated and still counts every exchange and violation."""
    _, short_size, short_rss = decode_with_report(tmp_path, SHORT_FRAMES)
    page, size, rss_mb = decode_with_report(tmp_path, LONG_FRAMES)
    print(f"{SHORT_FRAMES} frames: report {short_size / 1e6:.2f} MB, peak RSS {short_rss:.0f} MB; "
          f"{LONG_FRAMES} frames: report {size / 1e6:.2f} MB, peak RSS {rss_mb:.0f} MB")
    assert size < MAX_REPORT_BYTES and rss_mb < MAX_RSS_MB
    assert size - short_size < MAX_GROWTH_BYTES, (short_size, size)
    assert rss_mb - short_rss < MAX_GROWTH_MB, (short_rss, rss_mb)
    data = embedded(page, "session-data")
    assert data["counts"]["records"] == LONG_FRAMES
    assert data["counts"]["exchanges"] == LONG_FRAMES // 2
    assert data["counts"]["marks"] == LONG_FRAMES // 2 // 1000  # one letter-o per 1,000 exchanges
    assert data["counts"]["kept"] <= Limits().records + Limits().violation_records
    assert "A long capture" in page and '"activity"' in page


def test_timeout_records_are_marked_on_the_device_side():
    """A command left unanswered: the no-answer mark goes on the device lane (the device's duty) at the
    deadline, and the exchange is not counted."""
    records = analyze([Chunk(0.0, H, b"0RV\r\n"), Chunk(5.0, H, b"0RV\r\n"), Chunk(5.02, D, b"0RV100\r\n")])
    agg = SessionAggregator()
    for r in records:
        agg.add(r)
    [timeout] = [r for r in records if isinstance(r, TimeoutRecord)]
    [mark] = agg.marks
    assert (mark["code"], mark["side"], mark["x"]) == ("no-answer", "device", timeout.t)
    assert agg.exchange_count == 1


# Marks close in time (issue 40 item 8): lower-case hex and an alarm ignored 0.2 s apart, a letter O that
# overlaps the command before it, all before any answer said where the axis is; then two positions.
CLOSE_MARKS = ((0.00, H, b"0rpa\r\n"), (0.01, D, b"0%%01\r\n"), (0.20, H, b"0RV\r\n"),
               (0.21, D, b"0%%01\r\n"), (0.40, H, b"0%C\r\n"), (0.41, D, b"0%C00\r\n"), (0.60, H, b"0RV\r\n"),
               (0.602, H, b"ORS\r\n"),
               (0.62, D, b"0RV100\r\n"), (0.64, D, b"0RS02\r\n"), (1.00, H, b"0RC\r\n"),
               (1.01, D, b"0RC0000200123A\r\n"), (600.0, H, b"0RC\r\n"), (600.01, D, b"0RC0000200123A\r\n"))


def close_marks_aggregate() -> SessionAggregator:
    agg, analyzer = SessionAggregator(), Analyzer()
    for t, d, raw in CLOSE_MARKS:
        agg.feed(analyzer, Chunk(1_795_000_000.0 + t, d, raw))
    for r in analyzer.close():
        agg.add(r)
    return agg


def test_timeline_marks_say_their_code_on_hover_never_as_drawn_text():
    """Violation marks carry their code and its meaning as hover text (and the legend names each code),
    never as text drawn beside the mark, which overlapped where marks are close (issue 40 item 8); each
    code has its own colour and shape, so close marks of notices (one colour) still tell apart."""
    from sniffer.report import plots

    marks = [t for t in plots.timeline(close_marks_aggregate()).data if t.meta == "violation"]
    codes = [t.text[0] for t in marks]
    assert {"lowercase-hex", "alarm-ignored", "letter-o", "overlapping-command"} <= set(codes)
    for trace, code in zip(marks, codes, strict=True):
        assert "text" not in trace.mode
        assert trace.name.startswith(f"{code} (")
        assert all(h.startswith(f"{code} (") and h.endswith(spec.VIOLATION_TABLE[code].meaning)
                   for h in trace.hovertext)
    assert len({(t.marker.color, t.marker.symbol) for t in marks}) == len(marks)


def test_the_position_plot_draws_no_position_before_one_is_known():
    """Alarm answers say no position: they are drawn in a strip of their own above the position axis,
    never at a position (they were drawn at the highest position, before any answer had given one);
    and a position the aggregate does not know (None, whatever gives it) is not drawn."""
    from sniffer.report import plots

    agg = close_marks_aggregate()
    first_known = min(p[0] for p in agg.positions.items)
    agg.positions.add((first_known + 1.0, None, "0RC", None))
    agg.moves.add((first_known + 2.0, first_known + 2.5, first_known + 3.0, 0x123A, None, "0MV"))
    fig = plots.position(agg)
    alarms = [t for t in fig.data if t.meta == "alarm"]
    assert alarms and all(t.yaxis == "y2" for t in alarms)
    assert fig.layout.yaxis2.ticktext == ("alarms",)
    on_axis = [(x, y) for t in fig.data if t.yaxis in (None, "y") for x, y in zip(t.x, t.y, strict=True)
               if y is not None]
    assert on_axis and all(x >= first_known * 1000.0 for x, _ in on_axis), on_axis
    assert all(isinstance(y, int) for _, y in on_axis)


@pytest.mark.slow  # starts a process
def test_proxy_report_written_on_sigterm(tmp_path):
    """``xac1 proxy --report``: the report is written when the run ends (here on SIGTERM) and holds the
    exchanges and violations the proxy printed (docs/protocol.md "Violation codes")."""
    import signal

    from test_sniffer_cli import Cli, no_traceback

    from xac1_proto.client import Client
    from xac1_proto.sim import SimConfig, serve_pty

    out = tmp_path / "proxy.html"
    with serve_pty(SimConfig(time_scale=0)) as sim, \
            Cli("proxy", "--device", sim.path, "--tcp", "127.0.0.1:0", "--format", "jsonl",
                "--report", str(out)) as cli:
        port = int(cli.wait_err(r"tcp 127\.0\.0\.1:(\d+)").group(1))
        with Client(f"socket://127.0.0.1:{port}") as client:
            client.read_version()
            client.transact(b"ORV\r\n")  # letter O for zero: alarm 01
            client.transact(b"0RV\r\n")  # without a reset: alarm-ignored; the latched alarm answers
            cli.records(6)
        assert cli.finish(signal.SIGTERM) == 0
        no_traceback(cli)
    records = [r for r in cli.all_records() if r["type"] != "summary"]
    data = embedded(out.read_text(encoding="utf-8"), "session-data")
    assert [r["violations"] for r in data["records"]] == [r["violations"] for r in records]
    assert data["counts"]["exchanges"] == 3
    assert {"letter-o", "alarm-ignored"} <= {c for r in records for c in r["violations"]}


def test_turnaround_histogram_fragment_for_other_reports():
    """``figures.turnaround_histogram``: an HTML fragment (no plotly.js in it: the page inlines it once)
    with one histogram per command and the deadline line, for the conformance report to embed."""
    from xac1_proto.pages import figures

    fragment = figures.turnaround_histogram({"0RV": [2.0, 2.5, 3.0], "0RP": [4.0]}, title="Turnaround <x>")
    assert fragment.startswith("<div") and "Plotly.newPlot" in fragment
    assert "plotly.min.js" not in fragment and len(fragment) < 20_000
    assert '"name":"0RV"' in fragment and '"x":[2.0,2.5,3.0]' in fragment and "deadline 1000 ms" in fragment
    assert "Turnaround &lt;x&gt;" in fragment


def test_group_summary_fragment_for_other_reports():
    """``figures.group_summary``: one stacked bar per group of its outcome counts, as a fragment."""
    from xac1_proto.pages import figures

    fragment = figures.group_summary({"framing": {"passed": 9, "failed": 1}, "alarms": {"skipped": 2}})
    assert "Plotly.newPlot" in fragment and "plotly.min.js" not in fragment
    assert '"name":"passed"' in fragment and '"x":[9,0]' in fragment and '"x":[1,0]' in fragment
    assert '"x":[0,2]' in fragment and '"y":["framing","alarms"]' in fragment
