"""``xac1 parse``: decode one frame as it appears on the wire, or explain what is wrong with it."""

from __future__ import annotations

import argparse
import sys

from .. import spec
from ..codec import diagnose, parse, show_bytes
from ..errors import FrameError

HELP = "decode one frame (text with \\r\\n escapes, or hex) and explain any error"


def wire_bytes(text: str, is_hex: bool) -> bytes:
    """The bytes a user means: ``0RP3\\r\\n`` with escapes, or ``30 52 50 33 0d 0a`` with --hex."""
    if is_hex:
        try:
            return bytes.fromhex(text.replace(":", " "))
        except ValueError as exc:
            raise SystemExit(f"xac1 parse: --hex: {exc}; give pairs of hex digits, e.g. "
                             f"'30 52 56 0d 0a'") from None
    try:
        return text.encode("latin-1").decode("unicode_escape").encode("latin-1")
    except (UnicodeError, ValueError) as exc:
        raise SystemExit(f"xac1 parse: cannot read escapes in {text!r}: {exc}") from None


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("text", metavar="TEXT",
                   help="the frame as on the wire, e.g. '0RP3\\r\\n' (escapes: \\r \\n \\xNN)")
    p.add_argument("--role", choices=spec.ROLES, required=True,
                   help="command (host to controller) or answer (controller to host)")
    p.add_argument("--hex", action="store_true", help="TEXT is hex bytes, e.g. '30 52 56 0d 0a'")


def run(args: argparse.Namespace) -> int:
    data = wire_bytes(args.text, args.hex)
    if not data.endswith(b"\n"):
        print(f"note: {show_bytes(data)} has no LF at the end; frames end with CR LF "
              f"(write it as '...\\r\\n')", file=sys.stderr)
    try:
        frame = parse(data, args.role)
    except FrameError as exc:
        print(f"error: {exc}", file=sys.stderr)
        lenient, violations = diagnose(data, args.role)
        if len(violations) > 1:
            print("every deviation found:", file=sys.stderr)
            for v in violations:
                print(f"  - {v.message}", file=sys.stderr)
        if lenient is not None:
            print(f"read leniently as: {lenient}", file=sys.stderr)
            fixed = lenient.to_bytes() if exc.code in ("letter-o", "lowercase-hex") else None
            if fixed is not None:
                print(f"the well-formed frame is: {show_bytes(fixed)}", file=sys.stderr)
        return 2
    fs = frame.frame_spec()
    print(frame)
    print(f"  {fs.meaning}; {fs.length} bytes")
    for name, value in frame.fields().items():
        field = spec.FIELDS[name]
        shown = value if field.text else field.show(value)
        extra = f"  {spec.alarm_meaning(value)}" if name == "code" else ""
        print(f"  {field.label:>4} = {shown}  ({field.doc}){extra}")
    _, notices = diagnose(data, args.role)
    for v in notices:
        print(f"  notice: {v.message}")
    return 0
