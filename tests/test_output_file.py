"""Paths that are not ours (issue 24 item 6): ``--report`` of decode, sniff, proxy and conformance and
``xac1 sim --state`` write through a symbolic link to its target, atomically, and refuse, before
anything starts (exit 2), whatever is not a regular file: a FIFO, a device node, a directory."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from conftest import CAPTURES, budget, xac1
from hypothesis import given, settings
from hypothesis import strategies as st

from conformance.plugin import check_outputs
from sniffer.report import ReportError, SessionReport
from xac1_proto.cli import main
from xac1_proto.output_file import OutputFileError, check_output, write_output
from xac1_proto.sim.model import PointData
from xac1_proto.sim.state import load_state, save_state

CAPTURE = str(CAPTURES / "socat-xv.log")


def odd(tmp_path: Path, kind: str) -> Path:
    """A path that is not a regular file: a FIFO, a link to a device node, a directory."""
    p = tmp_path / f"{kind}.html"
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "device-link":
        p.symlink_to("/dev/null")
    else:
        p.mkdir()
    return p


@settings(max_examples=budget(25))
@given(st.binary(max_size=2000), st.booleans())
def test_writing_through_a_link_replaces_the_target_and_keeps_the_link(tmp_path_factory, data: bytes,
                                                                       existed: bool) -> None:
    """Whatever the bytes, ``write_output`` through a symbolic link leaves the link as it was and the
    target holding exactly the bytes, with the target's permission bits kept; no temporary is left."""
    d = tmp_path_factory.mktemp("out")
    target, link = d / "real.html", d / "link.html"
    if existed:
        target.write_text("old")
        target.chmod(0o640)
    link.symlink_to(target.name)
    assert write_output(link, data) == target
    assert link.is_symlink() and os.readlink(link) == target.name
    assert target.read_bytes() == data
    if existed:
        assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert sorted(p.name for p in d.iterdir()) == ["link.html", "real.html"]


@pytest.mark.parametrize("kind", ["fifo", "device-link", "directory"])
def test_what_is_not_a_regular_file_is_refused_and_left_alone(tmp_path: Path, kind: str) -> None:
    """``check_output`` and ``write_output`` refuse a FIFO, a device (through a link) or a directory,
    naming the option, the path and what it is; the thing is left as it was."""
    p = odd(tmp_path, kind)
    what = {"fifo": "a FIFO", "device-link": "a character device", "directory": "a directory"}[kind]
    with pytest.raises(OutputFileError, match=f"--report {p}.*: it is {what}"):
        check_output(p, "--report")
    if kind != "directory":
        with pytest.raises(OutputFileError, match=f"it is {what}"):
            write_output(p, "x")
    assert {"fifo": stat.S_ISFIFO, "device-link": stat.S_ISCHR, "directory": stat.S_ISDIR}[kind](
        p.stat().st_mode)
    assert (kind == "device-link") == p.is_symlink()


def test_session_report_writes_through_a_link(tmp_path: Path) -> None:
    """The session report (decode, sniff, proxy ``--report``) named by a link: the page goes to the
    link's target, the link stays a link (was: the link itself replaced by a regular file)."""
    target, link = tmp_path / "real.html", tmp_path / "link.html"
    link.symlink_to(target)
    SessionReport.open(link, [("x", "socat")]).write()
    assert link.is_symlink() and "<html" in target.read_text(encoding="utf-8").lower()


@pytest.mark.parametrize("kind", ["fifo", "device-link"])
def test_session_report_refuses_a_fifo_or_device(tmp_path: Path, kind: str) -> None:
    """``SessionReport.open`` (before decode, sniff or proxy start) refuses a FIFO or a device node."""
    with pytest.raises(ReportError, match="not a regular file"):
        SessionReport.open(odd(tmp_path, kind), [])


@pytest.mark.parametrize("kind", ["fifo", "device-link"])
def test_decode_report_to_a_fifo_or_device_exits_2_before_decoding(tmp_path: Path, kind: str,
                                                                   capsys) -> None:
    """``xac1 decode --report`` to a FIFO or a link to ``/dev/null``: exit 2, nothing decoded, the path
    named; the FIFO and the link are left as they were."""
    p = odd(tmp_path, kind)
    assert main(["decode", CAPTURE, "--report", str(p)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and f"cannot write the report {p}" in err and "not a regular file" in err
    assert stat.S_ISFIFO(p.stat().st_mode) if kind == "fifo" else p.is_symlink()


@pytest.mark.parametrize("kind", ["fifo", "device-link"])
def test_conformance_outputs_refuse_a_fifo_or_device(tmp_path: Path, kind: str) -> None:
    """``conformance --report``/``--junit`` to a FIFO or a device node is refused before anything is
    sent (the check ``xac1 conformance`` makes first)."""
    p = odd(tmp_path, kind)
    problem = check_outputs(str(p), None, lambda name: f"--{name}")
    assert problem is not None and problem.startswith(f"--report {p}") and "not a regular file" in problem
    junit = p.with_suffix(".xml")
    os.rename(p, junit)
    problem = check_outputs(None, str(junit), lambda name: f"--{name}")
    assert problem is not None and "not a regular file" in problem


def test_sim_state_through_a_link_keeps_the_link(tmp_path: Path) -> None:
    """The simulator's state file named by a link: saved to the link's target, the link stays, and it
    loads back (was: the link replaced by a regular file)."""
    target, link = tmp_path / "table.json", tmp_path / "state-link.json"
    link.symlink_to(target)
    table = {5: PointData(9, 3, 0, 0x12345)}
    save_state(link, table)
    assert link.is_symlink() and load_state(target) == table == load_state(link)


@pytest.mark.slow
def test_sim_refuses_a_fifo_state_file_before_it_starts(tmp_path: Path) -> None:
    """``xac1 sim --state FIFO``: exit 2 with the path named, before serving (was: blocked reading the
    FIFO, then would have replaced it)."""
    fifo = odd(tmp_path, "fifo")
    done = xac1("sim", "--pty", "--state", str(fifo), timeout=20)
    assert done.returncode == 2 and f"--state {fifo}" in done.stderr and "a FIFO" in done.stderr
    assert stat.S_ISFIFO(fifo.stat().st_mode) and "Traceback" not in done.stderr


@pytest.mark.parametrize("command", ["sniff", "proxy"])
def test_sniff_and_proxy_refuse_a_fifo_report_before_opening_anything(tmp_path: Path, command: str,
                                                                       capsys) -> None:
    """``xac1 sniff``/``xac1 proxy --report FIFO``: exit 2 naming the path before any port is opened (the
    ports named here do not exist: the report's error comes first); the FIFO is left alone."""
    fifo = odd(tmp_path, "fifo")
    ports = (["--host-tap", str(tmp_path / "no-tap-1"), "--device-tap", str(tmp_path / "no-tap-2")]
             if command == "sniff" else ["--device", str(tmp_path / "no-device"), "--tcp", "127.0.0.1:0"])
    assert main([command, *ports, "--report", str(fifo)]) == 2
    err = capsys.readouterr().err
    assert f"cannot write the report {fifo}" in err and "a FIFO" in err and "no-" not in err
    assert stat.S_ISFIFO(fifo.stat().st_mode)
