"""The tables of docs/protocol.md, generated from ``spec.py`` so that the page cannot drift from the code.

How this works: docs/protocol.md holds marker comments ``<!-- generated: NAME -->`` ...
``<!-- end generated -->``; ``update(text)`` replaces what lies between each pair with ``TABLES[NAME]()``
rendered from the spec tables (``FRAME_SPECS`` for "Frames", ``ALARMS`` for "Alarms",
``rules.RULE_ROWS`` for "Violation codes", ``latch.LATCH`` for the latch's state machine). Everything
outside the markers is hand-written and kept.
``python -m xac1_proto.docgen --write`` rewrites the page in place; ``--check`` exits 1 when it is out of
date (a test runs the same comparison).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Final

from . import latch, rules, spec

DEFAULT_PATH: Final = Path(__file__).resolve().parent.parent / "docs" / "protocol.md"
END: Final = "<!-- end generated -->"
_BLOCK: Final = re.compile(r"(<!-- generated: ([a-z-]+) -->\n)(.*?)(" + re.escape(END) + ")", re.DOTALL)

_DUTY_TEXT: Final[dict[spec.Duty, str]] = {
    spec.HOST_SIDE: "host",
    spec.DEVICE_SIDE: "device",
    spec.SENDER: "sender of the bytes",
}


class DocError(ValueError):
    """docs/protocol.md lacks a marker pair, or names a table this module does not generate."""


def _layout(header: str, layout: tuple[spec.Item, ...]) -> str:
    """A frame layout as the page writes it: literal characters in backticks, field labels bare."""
    parts = [f"`{header}`"]
    for item in layout:
        parts.append(spec.FIELDS[item].label if isinstance(item, str) else f"`{item.text}`")
    return " ".join(parts)


def frames_table() -> str:
    """One row a header: the command and its answer, their layouts and byte counts (CR LF included)."""
    rows = ["| cmd | meaning | command | bytes | answer | bytes |", "|---|---|---|---|---|---|"]
    headers = list(dict.fromkeys(s.header for s in spec.FRAME_SPECS))
    for header in headers:
        command = spec.SPECS.get((header, spec.COMMAND))
        answer = spec.SPECS[(header, spec.ANSWER)]
        if command is None:
            cmd_cells = ["-", "-"]
            meaning = answer.meaning
        else:
            cmd_cells = [_layout(header, command.layout), str(command.length)]
            meaning = command.meaning
        echo = " (echo of the command)" if answer.echo else ""
        ans_cells = [_layout(header, answer.layout) + echo, str(answer.length)]
        rows.append(f"| `{header}` | {meaning} | " + " | ".join(cmd_cells + ans_cells) + " |")
    return "\n".join(rows)


def alarms_table() -> str:
    """One row an alarm code the vendor lists."""
    rows = ["| Ec | answer | meaning |", "|---|---|---|"]
    field = spec.FIELDS["code"]
    for code, meaning in spec.ALARMS.items():
        shown = field.show(code)
        text = meaning or "listed with no meaning (reserved; notice `reserved-alarm`)"
        rows.append(f"| `{shown}` | `{spec.ALARM_HEADER}{shown}` | {text} |")
    return "\n".join(rows)


def violations_table() -> str:
    """One row a rule of the rulebook (``rules.RULE_ROWS``), in report order: its code, severity (derived
    from its basis), whose duty, what it checks and its basis."""
    rows = ["| code | rule | severity | whose duty | checks | basis |", "|---|---|---|---|---|---|"]
    for r in rules.RULE_ROWS:
        rows.append(f"| `{r.code}` | {r.name} | {r.severity} | {_DUTY_TEXT[r.duty]} | {r.checks} | "
                    f"{r.basis.show()} |")
    return "\n".join(rows)


def _latch_cell(cell: latch.Transition) -> str:
    """A cell of the latch table: the rule broken (``-``: none) and, after an arrow, the effect when the
    event does something."""
    rule = f"`{cell.rule}`" if cell.rule else "-"
    return rule if cell.effect is latch.Effect.KEEP else f"{rule} → {cell.effect.name}"


def latch_table() -> str:
    """The alarm latch's state machine (``latch.LATCH``): one row an event, one column a state, each cell
    ``_latch_cell``; then what the states and effects are, and the storm run's table."""
    states = list(latch.LatchState)
    rows = ["| event | " + " | ".join(s.name for s in states) + " |", "|---|" + "---|" * len(states)]
    for event in latch.LatchEvent:
        cells = [_latch_cell(latch.LATCH[(state, event)]) for state in states]
        rows.append(f"| {event.name}: {event.value} | " + " | ".join(cells) + " |")
    effects = [f"{e.name}: {e.value}" for e in latch.Effect if e is not latch.Effect.KEEP]
    storm = [f"{state.name} ({state.value}), {'the reset' if reset else 'another line'}: "
             f"{f'`{rule}`' if rule else 'nothing'}" for (state, reset), rule in latch.HOST_DUTY.items()]
    rows += ["", "States: " + "; ".join(f"{s.name}: {s.value}" for s in states) + ". Effects: "
             + "; ".join(effects) + ".", "", "The storm run (`HOST_DUTY`): " + "; ".join(storm) + "."]
    return "\n".join(rows)


TABLES: Final[dict[str, Callable[[], str]]] = {
    "frames": frames_table,
    "alarms": alarms_table,
    "violations": violations_table,
    "latch": latch_table,
}


def update(text: str) -> str:
    """``text`` with every generated block rendered afresh; raises DocError on a missing or unknown block."""
    seen: set[str] = set()

    def render(m: re.Match[str]) -> str:
        name = m.group(2)
        if name not in TABLES:
            raise DocError(f"docs/protocol.md: unknown generated block {name!r}; known: {', '.join(TABLES)}")
        seen.add(name)
        return f"{m.group(1)}{TABLES[name]()}\n{m.group(4)}"

    out = _BLOCK.sub(render, text)
    missing = [n for n in TABLES if n not in seen]
    if missing:
        raise DocError(f"docs/protocol.md: no '<!-- generated: {missing[0]} -->' ... '{END}' block "
                       f"(missing: {', '.join(missing)})")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m xac1_proto.docgen", description=__doc__.splitlines()[0])
    parser.add_argument("--path", type=Path, default=DEFAULT_PATH,
                        help="the page (default: docs/protocol.md)")
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", action="store_true", help="rewrite the generated tables in place")
    mode.add_argument("--check", action="store_true", help="exit 1 when the tables are out of date")
    args = parser.parse_args(argv)
    try:
        text = args.path.read_text(encoding="utf-8")
        fresh = update(text)
    except (OSError, DocError) as exc:
        print(f"docgen: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if fresh != text:
            print(f"docgen: {args.path} is out of date: run python -m xac1_proto.docgen --write",
                  file=sys.stderr)
            return 1
        return 0
    if fresh != text:
        args.path.write_text(fresh, encoding="utf-8")
        print(f"docgen: rewrote the generated tables of {args.path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
