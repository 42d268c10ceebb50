"""``xac1 fuzz``'s sans-IO core: hostile lines from the grammar, never a move, findings, the shrinker.

``guard`` reads every line as the most lenient controller might and refuses a motion header anywhere in
it; ``cases`` makes seeded cases (mutations of well-formed frames built from ``spec.py``, and plain
random bytes), each passed through the guard; ``judge`` turns what the unit answered into findings
(``silence``, ``answer``, ``state``) and keeps what the cases themselves wrote; ``shrink`` reduces a
finding's lines; ``results`` holds a run's cases, findings and summary as plain data. Nothing here opens
a port, reads a clock or starts a thread: the shell (``xac1_proto.cli.fuzz_cmd``) does. Importing the
package loads no submodule.
"""
