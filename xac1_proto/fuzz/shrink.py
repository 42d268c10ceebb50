"""The shrinker: the fewest and shortest lines that still produce a finding.

How this works: ``shrink(lines, still, budget)`` is delta debugging over the writes, then over the bytes
of each write. First whole writes are left out, in halves, quarters... down to one at a time; then each
write loses runs of bytes, long runs first (a 1000-byte line that hangs the unit at 41 takes a few dozen
tries, not a thousand). A candidate is kept when ``still(candidate)`` says it produces the same kind of
finding (the shell re-runs it against a fresh unit). Every candidate is first made whole the way cases
are (``cases.finish``: motion guard, write filter, closing LF), and one that the motion guard changed is
skipped: shrinking never invents a move by cutting the bytes between ``0M`` and ``P``. ``budget`` bounds
the calls to ``still``; ``stop()`` (a signal) ends the shrinking with the best found so far.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import guard
from .cases import Context, finish

Lines = tuple[bytes, ...]


@dataclass
class Shrunk:
    """The result: the lines kept, how many re-runs it took, whether the budget ran out first."""

    lines: Lines
    tries: int
    exhausted: bool


def _size(lines: Lines) -> tuple[int, int]:
    return len(lines), sum(len(line) for line in lines)


def shrink(lines: Lines, still: Callable[[Lines], bool], ctx: Context, *, budget: int = 200,
           stop: Callable[[], bool] = lambda: False) -> Shrunk:
    """Reduce ``lines`` while ``still`` holds (see the module docstring)."""
    best = lines
    seen: set[Lines] = {best}
    tries = 0

    def attempt(candidate: list[bytes]) -> bool:
        nonlocal best, tries
        raw = [c for c in candidate if c]
        if not raw or tries >= budget or stop():
            return False
        made = finish("shrink", raw, ctx).lines
        if guard.motion_at(b"".join(raw)) is not None or made in seen or _size(made) >= _size(best):
            return False
        seen.add(made)
        tries += 1
        if still(made):
            best = made
            return True
        return False

    changed = True
    while changed and tries < budget and not stop():
        changed = False
        n = len(best)
        step = max(n // 2, 1)
        while step >= 1 and len(best) > 1:  # leave writes out
            i = 0
            while i < len(best):
                if attempt(list(best[:i]) + list(best[i + step:])):
                    changed = True
                else:
                    i += step
            step //= 2
        for k in range(len(best)):  # shorten each write
            if k >= len(best):
                break
            run = max(len(best[k]) // 2, 1)
            while run >= 1:
                line = best[k]
                at = 0
                while at < len(best[k]):
                    line = best[k]
                    if attempt([*best[:k], line[:at] + line[at + run:], *best[k + 1:]]):
                        changed = True
                    else:
                        at += run
                run //= 2
    return Shrunk(best, tries, tries >= budget)
