"""The simulator answering as a captured device did (``xac1 sim --replay``, ``xac1sim://?replay=FILE``).

How it works (sans-IO, like the model): ``ReplayingDevice`` is a ``DeviceModel`` whose ``receive`` cuts
the host's bytes into lines at LF and asks the script's cursor (``xac1_proto.replay.ScriptCursor``) for
the next captured line equal to each one (a host that repeats or retries still lines up). A line found
is answered with the captured answer bytes, each after its captured turnaround (from the line's last
byte; scaled by ``time_scale``; the configured turnaround where the capture had no time), through the
model's outbox (line faults and wire timing apply as to any answer); a line the capture left unanswered
stays unanswered. A line the capture does not hold next is answered by the model (default) or not at
all (``strict``); either way ``on_note`` is told (the shell prints it: stderr and the sim's log).

The script comes from a capture file through a plug-in (``load_script``: the entry-point group
``xac1_proto.replay_scripts``; the sniffer registers ``capture``, which reads every format ``xac1 decode``
reads): the core names no sniffer.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Final

from ..codec import show_bytes
from ..framer import MAX_FRAME
from ..replay import Script, ScriptCursor
from .config import SimConfig
from .model import DeviceModel, PointData
from .outbox import Output

SCRIPTS_GROUP: Final = "xac1_proto.replay_scripts"  # entry points: name -> loader(files, fmt, host_is)
LOADER: Final = "capture"
NOTES_KEPT: Final = 100  # notes kept in ``notes`` (all are counted and told to ``on_note``)


class ReplayError(ValueError):
    """The capture cannot be replayed (unreadable, no host line, no loader installed)."""


def load_script(files: Sequence[str], input_format: str = "auto", host_is: str | None = None) -> Script:
    """The script of a capture through the installed loader; ReplayError saying why not."""
    from importlib.metadata import entry_points

    for entry in entry_points(group=SCRIPTS_GROUP):
        if entry.name == LOADER:
            loader = entry.load()
            try:
                script: Script = loader(list(files), input_format, host_is)
            except ValueError as exc:
                raise ReplayError(str(exc)) from None
            return script
    raise ReplayError(f"no capture reader is installed (entry point {SCRIPTS_GROUP}:{LOADER}); install "
                      f"xac1-proto with its sniffer package")


class ReplayingDevice(DeviceModel):
    """A device model that answers from a script first (module docstring). ``cursor.where()`` says
    where the replay stands; ``notes`` keeps every line that was not in the capture next."""

    def __init__(self, script: Script, config: SimConfig | None = None, *, strict: bool = False,
                 points: Mapping[int, PointData] | None = None,
                 on_note: Callable[[str], None] | None = None) -> None:
        super().__init__(config, points)
        self.cursor = ScriptCursor(script)
        self.strict = strict
        self.on_note = on_note
        self.notes: list[str] = []
        self._replay_buffer = bytearray()

    def receive(self, data: bytes, t: float) -> list[Output]:
        outs: list[Output] = []
        self._replay_buffer += data
        while True:
            lf = self._replay_buffer.find(b"\n")
            if lf < 0:
                if len(self._replay_buffer) > MAX_FRAME * 16:  # no LF for this long: a line of its own
                    lf = len(self._replay_buffer) - 1
                else:
                    break
            line = bytes(self._replay_buffer[: lf + 1])
            del self._replay_buffer[: lf + 1]
            outs += self._replay_line(line, t)
        return outs

    def _replay_line(self, line: bytes, t: float) -> list[Output]:
        match = self.cursor.match(line)
        if match is not None:
            if match.skipped:
                self._note(f"{match.skipped} captured line(s) passed over to reach {show_bytes(line)}")
            cfg = self.config
            return [self.outbox.put(answer.raw, t + (cfg.turnaround_s if delay is None else delay)
                                    * cfg.time_scale, cfg.wire_timing)
                    for answer, delay in match.answers]
        how = "not answered (--replay-strict)" if self.strict else "answered by the model"
        self._note(f"{show_bytes(line)} is not in the rest of the capture: {how}")
        return [] if self.strict else super().receive(line, t)

    def _note(self, text: str) -> None:
        note = f"{text} ({self.cursor.where()})"
        if len(self.notes) < NOTES_KEPT:
            self.notes.append(note)
        if self.on_note is not None:
            self.on_note(note)

    def reset_line(self) -> None:
        self._replay_buffer.clear()
        super().reset_line()

    def replay_where(self) -> str:
        """Where the replay stands (the control channel's ``replay``)."""
        return self.cursor.where()
