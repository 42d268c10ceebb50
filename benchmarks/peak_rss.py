"""Peak resident memory of one command, exactly, whatever the size of the process that asks.

``os.wait4`` on a child started by a large process overstates: Linux keeps, in the child's
``ru_maxrss``, the high-water mark of the memory it had before ``exec``, and a child forked (or
vforked) by a 150 MB pytest worker *is* that worker until it execs. So the command is started by a
small trampoline instead (a bare ``python -I -S``): the trampoline forks, the copy execs the command,
and the trampoline reports the command's ``ru_maxrss`` on a pipe. What the command is charged before
its exec is the trampoline's few MB, below any Python program's own peak.

Used by the memory benchmarks and by the tests that bound the decoder's memory.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

_TRAMPOLINE = """\
import os, sys
report, command = int(sys.argv[1]), sys.argv[2:]
pid = os.fork()
if pid == 0:
    os.close(report)
    try:
        os.execvp(command[0], command)
    finally:
        os._exit(127)
_, status, usage = os.wait4(pid, 0)
os.write(report, str(usage.ru_maxrss).encode())
code = os.waitstatus_to_exitcode(status)
sys.exit(128 - code if code < 0 else code)
"""


def run_measuring_peak_rss(args: Sequence[str], cwd: Path | None = None,
                           env: Mapping[str, str] | None = None) -> tuple[int, float]:
    """Run ``args`` (output discarded) and return its exit status and its peak RSS in MiB.

    The status is the command's own (128 + N when signal N ended it; 127 when it could not start).
    The trampoline adds about 10 ms of its own start to the command's wall time.
    """
    read_end, write_end = os.pipe()
    try:
        proc = subprocess.Popen([sys.executable, "-I", "-S", "-c", _TRAMPOLINE, str(write_end), *args],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=cwd, env=env,
                                pass_fds=(write_end,))
        os.close(write_end)
        write_end = -1
        with os.fdopen(read_end, "rb") as report:
            read_end = -1
            kib = report.read()
        code = proc.wait()
    finally:
        for fd in (read_end, write_end):
            if fd >= 0:
                os.close(fd)
    if not kib:
        raise RuntimeError(f"the peak-RSS trampoline for {args[0]} reported nothing (exit {code})")
    return code, int(kib) / 1024
