"""Fuzz cases: hostile byte sequences made from the grammar, seeded, each one a move-free case.

How this works: a case is the bytes written to the line in one or more writes (``Case.lines``; the
shell waits for answers after each). Every generator starts from the spec's tables (``spec.FRAME_SPECS``,
``spec.FIELDS``): a well-formed command of a random kind with random in-range fields (``base_frame``,
never a motion command), then spoils it: bytes flipped, inserted or dropped, a field out of range, lower
case, the letter O for the leading zero, a wrong terminator, a line of a length around the frame sizes
or well past them, NUL and bytes above 0x7F, a flood of short lines, a partial frame followed by
silence, two frames back to back; ``random`` is plain random bytes. ``finish`` makes every case safe and
whole: the motion guard's ``defuse`` (no ``0MP``/``0MV`` however leniently read), no write to a point
the run may not write (``Context.writable``: on a real device the points it can write back), and a
closing LF when the case would end inside a line, so the probe after it starts on a fresh line. The
``random.Random`` given decides everything: the same seed gives the same cases.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Final

from .. import spec
from ..codec import diagnose
from ..framer import MAX_FRAME
from ..frames import FRAME_CLASSES, Frame, MoveDirect, StoreCurrent, WritePoint
from . import guard

LF: Final = spec.FRAME_END
ALL_POINTS: Final = frozenset(range(spec.FIELDS["n"].command_range[0], spec.FIELDS["n"].command_range[1] + 1))
# The commands a case is built from: every command of the spec but the moves.
BASE_SPECS: Final = tuple(fs for fs in spec.FRAME_SPECS
                          if fs.role == spec.COMMAND and fs.header not in spec.MOVE_HEADERS)
_WRITES: Final = frozenset({WritePoint.HEADER, StoreCurrent.HEADER})
FRAME_LENGTHS: Final = tuple(sorted({fs.length for fs in spec.FRAME_SPECS}))
# Lines "well past" the frame sizes: around the framer's limit and beyond.
LONG_LENGTHS: Final = (MAX_FRAME - 1, MAX_FRAME, MAX_FRAME + 1, 2 * MAX_FRAME, 255, 256, 1024)


@dataclass(frozen=True)
class Case:
    """One case: its generator's name and the writes it makes (``lines``), in order."""

    kind: str
    lines: tuple[bytes, ...]
    motion: bool = False  # a move inside the safe range (--allow-motion): sent through the motion guard

    @property
    def data(self) -> bytes:
        return b"".join(self.lines)


@dataclass(frozen=True)
class Context:
    """What a case may contain: the points it may write, the safe range for moves (None: no moves)."""

    writable: frozenset[int] = ALL_POINTS
    safe_range: tuple[int, int] | None = None


Generator = Callable[[random.Random, Context], list[bytes]]


def base_frame(rng: random.Random, ctx: Context) -> Frame:
    """A well-formed command of a random kind (no move; a write only to a writable point)."""
    specs = [fs for fs in BASE_SPECS if fs.header not in _WRITES or ctx.writable]
    fs = rng.choice(specs)
    values: dict[str, int] = {}
    for name in fs.field_names:
        lo, hi = fs.field_range(name)
        values[name] = rng.choice(sorted(ctx.writable)) if name == "n" and fs.header in _WRITES \
            else rng.randint(lo, hi)
    frame: Frame = FRAME_CLASSES[fs.key](**values)  # type: ignore[arg-type]  # checked by its class
    return frame


def _base(rng: random.Random, ctx: Context) -> bytes:
    return base_frame(rng, ctx).to_bytes()


def _byte(rng: random.Random) -> int:
    return rng.randrange(256)


def flip(rng: random.Random, ctx: Context) -> list[bytes]:
    """One to three bits flipped in a well-formed frame."""
    data = bytearray(_base(rng, ctx))
    for _ in range(rng.randint(1, 3)):
        data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
    return [bytes(data)]


def insert(rng: random.Random, ctx: Context) -> list[bytes]:
    """One to four random bytes inserted into a well-formed frame."""
    data = bytearray(_base(rng, ctx))
    for _ in range(rng.randint(1, 4)):
        data.insert(rng.randrange(len(data) + 1), _byte(rng))
    return [bytes(data)]


def drop(rng: random.Random, ctx: Context) -> list[bytes]:
    """One to three bytes dropped from a well-formed frame (a cable that loses bytes)."""
    data = bytearray(_base(rng, ctx))
    for _ in range(rng.randint(1, min(3, len(data) - 1))):
        del data[rng.randrange(len(data))]
    return [bytes(data)]


def field_range(rng: random.Random, ctx: Context) -> list[bytes]:
    """A field of a well-formed frame out of its range, or not a digit at all."""
    frame = base_frame(rng, ctx)
    fs = frame.frame_spec()
    if not fs.field_names:
        return [frame.to_bytes()[: spec.HEADER_WIDTH] + b"9" + spec.TERMINATOR]  # a field where none is
    name = rng.choice(fs.field_names)
    f, (lo, hi) = spec.FIELDS[name], fs.field_range(name)
    top = f.radix ** f.width - 1
    outside = [v for v in (lo - 1, hi + 1, top) if 0 <= v <= top and not lo <= v <= hi]
    text = f.show(rng.choice(outside)) if outside and rng.random() < 0.7 else \
        "".join(rng.choice("G:/ -Z") for _ in range(f.width))
    at = fs.offsets()[name]
    raw = frame.to_bytes()
    return [raw[:at] + text.encode("ascii") + raw[at + f.width:]]


def lower_case(rng: random.Random, ctx: Context) -> list[bytes]:
    """A well-formed frame in lower case (docs/protocol.md silent item 2)."""
    return [_base(rng, ctx).lower()]


def letter_o(rng: random.Random, ctx: Context) -> list[bytes]:
    """A well-formed frame starting with the letter O (the vendor PDF's artefact)."""
    return [spec.LETTER_O + _base(rng, ctx)[1:]]


TERMINATORS: Final = (b"\n", b"\r", b"\n\r", b"\r\r\n", b"", b"\r\n\r\n", b"\x00\r\n")


def terminator(rng: random.Random, ctx: Context) -> list[bytes]:
    """A well-formed body with a wrong terminator: LF only, CR without LF, none, doubled, reversed."""
    body = _base(rng, ctx)[: -len(spec.TERMINATOR)]
    return [body + rng.choice(TERMINATORS)]


def length(rng: random.Random, ctx: Context) -> list[bytes]:
    """A line of a length around a frame size or well past them, of frame text or random printables."""
    n = rng.choice([L + d for L in FRAME_LENGTHS for d in (-1, 0, 1)] + list(LONG_LENGTHS))
    seed = _base(rng, ctx)[: -len(spec.TERMINATOR)]
    if rng.random() < 0.5:
        body = (seed * (n // len(seed) + 1))[:n]
    else:
        body = bytes(rng.randrange(0x20, 0x7F) for _ in range(n))
    return [body[: max(n - len(spec.TERMINATOR), 0)] + spec.TERMINATOR]


def nul_high(rng: random.Random, ctx: Context) -> list[bytes]:
    """A well-formed frame with NUL bytes and bytes above 0x7F put in or over it."""
    data = bytearray(_base(rng, ctx))
    for _ in range(rng.randint(1, 3)):
        b = rng.choice((0x00, rng.randrange(0x80, 0x100)))
        at = rng.randrange(len(data) - 1)  # never over the LF: the line stays one line
        if rng.random() < 0.5:
            data[at] = b
        else:
            data.insert(at, b)
    return [bytes(data)]


def flood(rng: random.Random, ctx: Context) -> list[bytes]:
    """A flood of short lines in one write: empty lines, lone digits, bits of frames."""
    shorts = [LF, spec.TERMINATOR, b"0" + LF, b"\r", b"?" + spec.TERMINATOR, b"0R" + LF, b"%" + LF]
    return [b"".join(rng.choice(shorts) for _ in range(rng.randint(5, 40)))]


def partial(rng: random.Random, ctx: Context) -> list[bytes]:
    """A frame cut short, then silence (the shell waits the answer window), then its rest or a new line."""
    raw = _base(rng, ctx)
    cut = rng.randrange(1, len(raw) - 1)
    return [raw[:cut], raw[cut:] if rng.random() < 0.5 else _base(rng, ctx)]


def back_to_back(rng: random.Random, ctx: Context) -> list[bytes]:
    """Two frames in one write, with no wait for the first answer."""
    return [_base(rng, ctx) + _base(rng, ctx)]


def noise(rng: random.Random, ctx: Context) -> list[bytes]:
    """Plain random bytes (noise at power-up), one to 64 of them."""
    return [bytes(_byte(rng) for _ in range(rng.randint(1, 64)))]


# name -> generator; the run picks one at random for each case.
GENERATORS: Final[dict[str, Generator]] = {
    "flip": flip, "insert": insert, "drop": drop, "field-range": field_range, "lower-case": lower_case,
    "letter-o": letter_o, "terminator": terminator, "length": length, "nul-high": nul_high,
    "flood": flood, "partial": partial, "back-to-back": back_to_back, "random": noise,
}


def _unwritable_write(line: bytes, writable: frozenset[int]) -> int | None:
    """Offset of the header of a write (0WP, 0WC) to a point outside ``writable`` that a lenient
    controller could read in ``line`` (one line, up to its LF), or None."""
    text, where = guard.lenient(line)
    for header in _WRITES:
        at = text.find(header)
        if at < 0:
            continue
        start = where[at]
        for candidate in (line[start:], line[start:].upper()):
            frame, _ = diagnose(candidate, spec.COMMAND)
            if frame is None and candidate[spec.HEADER_WIDTH: spec.HEADER_WIDTH + 1]:
                return start  # unreadable N: it could be any point
            if frame is not None and getattr(frame, "n", None) not in writable:
                return start
    return None


def _no_foreign_writes(data: bytes, writable: frozenset[int]) -> bytes:
    """``data`` with the W of every write to an unwritable point replaced by X (per line)."""
    if writable == ALL_POINTS:
        return data
    out = bytearray()
    for line in data.split(LF):
        spoiled = bytearray(line)
        while (hit := _unwritable_write(bytes(spoiled), writable)) is not None:
            spoiled[hit + 1] = ord("X")
        out += spoiled + LF
    return bytes(out[:-1])


def finish(kind: str, lines: list[bytes] | tuple[bytes, ...], ctx: Context) -> Case:
    """The case made safe and whole: split back into the same writes after ``defuse`` and the write
    filter, empty writes left out, a closing LF added when the bytes end inside a line."""
    sizes = [len(line) for line in lines]
    data = guard.defuse(_no_foreign_writes(b"".join(lines), ctx.writable))
    out, at = [], 0
    for size in sizes:
        if size:
            out.append(data[at: at + size])
        at += size
    if not data.endswith(LF):
        out.append(LF)
    return Case(kind, tuple(out))


def move(rng: random.Random, ctx: Context) -> Case:
    """A well-formed direct move inside the safe range (only with --allow-motion)."""
    assert ctx.safe_range is not None
    lo, hi = ctx.safe_range
    vel_lo, vel_hi = spec.FIELDS["vel"].command_range
    a_lo, a_hi = spec.FIELDS["a"].command_range
    frame = MoveDirect(vel=rng.randint(vel_lo, vel_hi), a=rng.randint(a_lo, a_hi), pos=rng.randint(lo, hi))
    return Case("move", (frame.to_bytes(),), motion=True)


MOVE_SHARE: Final = 0.1  # with --allow-motion, about one case in ten is a move


def next_case(rng: random.Random, ctx: Context) -> Case:
    """One case, drawn by ``rng``."""
    if ctx.safe_range is not None and rng.random() < MOVE_SHARE:
        return move(rng, ctx)
    kind = rng.choice(sorted(GENERATORS))
    return finish(kind, GENERATORS[kind](rng, ctx), ctx)


def cases(seed: int, ctx: Context) -> Iterator[Case]:
    """The endless, reproducible stream of cases of ``seed``."""
    rng = random.Random(seed)
    while True:
        yield next_case(rng, ctx)
