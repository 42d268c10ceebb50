# xac1-proto's sigrok decoder: hand-written; its knowledge comes from tables.py (generated from spec.py).
"""The XA-C1 protocol decoder for libsigrokdecode (API version 3), stacked on the UART decoder.

How this works: the UART decoder's Python output gives, for each byte of each line, ``DATA`` (the
value), ``INVALID STOPBIT`` / ``PARITY ERROR`` when the byte was damaged on the wire, and ``FRAME``
(from the start bit to the stop bit). Each byte goes into its line's ``checks.Framer`` with its sample
span and UART error; each frame or junk run that comes out is checked (``checks.diagnose``) and
annotated over its samples, first start bit to last stop bit: the frame with its meaning (host row:
commands, device row: answers), its fields, each frame-level violation code once, and the UART errors
of its bytes. As ``xac1 decode`` does, a partial device frame quiet for ``DEVICE_IDLE_FLUSH_S`` becomes
junk (when the sample rate is known). Conversation rules are not judged here: ``xac1 decode`` of a
sigrok-cli UART export gives them.

OUTPUT_PYTHON (for a decoder stacked on this one), one packet a frame or junk run, ``[TYPE, SIDE,
DATA]`` with SIDE ``'host'`` or ``'device'``:
 - ``'FRAME'``: ``{'raw': bytes, 'role': 'command'|'answer', 'header': str|None, 'meaning': str,
   'fields': {name: value}|None, 'violations': [code, ...], 'uart_errors': [text, ...]}``
 - ``'JUNK'``: ``{'raw': bytes, 'reason': str, 'violations': ['garbage'], 'uart_errors': [...]}``
Bytes still pending at the end of the capture (no LF yet) are not shown: libsigrokdecode 0.5 tells a
stacked decoder nothing when the data ends.
"""

from __future__ import annotations

from typing import Any

import sigrokdecode as srd  # type: ignore[import-not-found]

from . import tables as T
from .checks import Event, Framer, codes, diagnose, escape, fields_text, meaning, shown

HOST, DEVICE = "host", "device"
FRAMING_ERROR = "UART framing error"
PARITY_ERROR = "UART parity error"


class Ann:
    """Annotation classes, in the order of ``Decoder.annotations``."""

    COMMAND, ANSWER, HOST_JUNK, DEVICE_JUNK, FIELDS, VIOLATION, NOTICE, UART_ERROR = range(8)


class Decoder(srd.Decoder):
    api_version = 3
    id = "xac1"
    name = "XA-C1"
    longname = "SUS XA-C1 actuator controller"
    desc = ("SUS XA-C1 RS-232C frames, fields and frame-level violations (xac1 decode of a UART export "
            "judges the conversation).")
    license = "mit"
    inputs = ["uart"]
    outputs = ["xac1"]
    tags = ["Embedded/industrial"]
    options = (
        {"id": "host", "desc": "UART line of the host (its commands)", "default": "tx",
         "values": ("tx", "rx")},
    )
    annotations = (
        ("command", "Host command"),
        ("answer", "Device answer"),
        ("host-junk", "Host junk (bytes that form no frame)"),
        ("device-junk", "Device junk (bytes that form no frame)"),
        ("fields", "Fields"),
        ("violation", "Violation (error)"),
        ("notice", "Violation (notice)"),
        ("uart-error", "UART error"),
    )
    annotation_rows = (
        ("host", "Host frames", (Ann.COMMAND, Ann.HOST_JUNK)),
        ("device", "Device frames", (Ann.ANSWER, Ann.DEVICE_JUNK)),
        ("fields", "Fields", (Ann.FIELDS,)),
        ("violations", "Violations", (Ann.VIOLATION, Ann.NOTICE, Ann.UART_ERROR)),
    )

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.samplerate: float | None = None
        self.framers = {HOST: Framer(), DEVICE: Framer()}
        self.byte: list[tuple[int, int] | None] = [None, None]  # per rxtx: (value, DATA's start sample)
        self.error: list[str | None] = [None, None]  # per rxtx: the UART error of the byte under way
        self.device_last: float | None = None  # time of the latest device byte
        self.wide_said = False  # the UART decoder gives values above a byte (9 data bits): said once

    def start(self) -> None:
        self.out_ann = self.register(srd.OUTPUT_ANN)
        self.out_python = self.register(srd.OUTPUT_PYTHON)
        chosen: dict[str, Any] = self.options  # type: ignore[assignment]  # sigrok: the values by id
        self.host_rxtx = 1 if chosen["host"] == "tx" else 0  # the UART decoder's RX is 0, TX 1

    def metadata(self, key: int, value: Any) -> None:
        if key == srd.SRD_CONF_SAMPLERATE:
            self.samplerate = value

    def decode(self, ss: int, es: int, data: list[Any]) -> None:
        ptype, rxtx, pdata = data
        if ptype == "DATA" and pdata[0] > 0xFF:  # the UART decoder set to 9 data bits: no XA-C1 byte
            if not self.wide_said:
                self.wide_said = True
                self.put(ss, es, self.out_ann, [Ann.UART_ERROR, [
                    f"UART decoder set wrong: a {pdata[0].bit_length()}-bit value; XA-C1 is 8N1 (set the "
                    f"uart decoder's data_bits=8)", "UART set wrong: XA-C1 is 8N1"]])
        elif ptype == "DATA":
            self.byte[rxtx] = (pdata[0], ss)
        elif ptype == "INVALID STOPBIT":
            self.error[rxtx] = FRAMING_ERROR
        elif ptype == "PARITY ERROR":
            self.error[rxtx] = PARITY_ERROR
        elif ptype == "FRAME":
            got, error = self.byte[rxtx], self.error[rxtx]
            self.byte[rxtx] = self.error[rxtx] = None
            if got is None:  # an invalid start bit: a glitch, no byte
                return
            if error is None and not pdata[1]:
                error = FRAMING_ERROR
            self._byte(HOST if rxtx == self.host_rxtx else DEVICE, got[0], got[1], ss, es, error)

    def _byte(self, side: str, value: int, data_ss: int, ss: int, es: int, error: str | None) -> None:
        t = data_ss / self.samplerate if self.samplerate else None
        device = self.framers[DEVICE]
        if (t is not None and device.pending and self.device_last is not None
                and t - self.device_last >= T.DEVICE_IDLE_FLUSH_S):
            for event in device.flush():  # as xac1 decode: a partial device frame gone quiet is junk
                self._event(DEVICE, event)
        if side == DEVICE:
            self.device_last = t
        for event in self.framers[side].feed(bytes([value]), [(ss, es, error)]):
            self._event(side, event)

    def _event(self, side: str, event: Event) -> None:
        ss, es = event.marks[0][0], event.marks[-1][1]
        uart_errors: list[str] = []
        for _, _, error in event.marks:
            if error is not None and error not in uart_errors:
                uart_errors.append(error)
        role = T.COMMAND if side == HOST else T.ANSWER
        if event.reason is not None:
            cls = Ann.HOST_JUNK if side == HOST else Ann.DEVICE_JUNK
            self.put(ss, es, self.out_ann, [cls, [f"{escape(event.raw)} {side} junk ({event.reason})",
                                                  f"{escape(event.raw)} junk", "junk"]])
            self.put(ss, es, self.out_ann, [Ann.VIOLATION, ["garbage"]])
            self.put(ss, es, self.out_python, ["JUNK", side, {
                "raw": event.raw, "reason": event.reason, "violations": ["garbage"],
                "uart_errors": uart_errors}])
        else:
            header, values, found = diagnose(event.raw, role)
            what = meaning(header, role, values)
            cls = Ann.COMMAND if side == HOST else Ann.ANSWER
            self.put(ss, es, self.out_ann, [cls, [f"{shown(event.raw)} {role}: {what}",
                                                  f"{shown(event.raw)} {what}", shown(event.raw)]])
            if values:
                self.put(ss, es, self.out_ann, [Ann.FIELDS, [fields_text(values)]])
            found_codes = codes(found)
            for code in found_codes:
                notice = T.VIOLATIONS[code][0] == "notice"
                self.put(ss, es, self.out_ann, [Ann.NOTICE if notice else Ann.VIOLATION, [code]])
            self.put(ss, es, self.out_python, ["FRAME", side, {
                "raw": event.raw, "role": role, "header": header, "meaning": what, "fields": values,
                "violations": found_codes, "uart_errors": uart_errors}])
        for error in uart_errors:
            self.put(ss, es, self.out_ann, [Ann.UART_ERROR, [error]])
