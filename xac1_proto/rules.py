"""The rulebook as data: every rule that yields a violation, with its code, whose duty and its basis.

How this works: each ``Rule`` row names one rule (``name``), the docs/protocol.md violation code it
reports (``code``; whose duty comes from the code's row in ``spec.VIOLATION_SPECS``) and its ``Basis``:
the vendor section and the text's own words when the vendor text states the rule (``stated``), or "our
reading" and the silent item of docs/protocol.md it rests on (``reading``), or a departure the text does
not forbid that is only worth telling (``information``: lower case, alarm codes with no meaning). The
severity is never written: it follows from the basis (stated: an error; reading and information: a
notice). ``severity(rule, readings)`` is that severity under a ``--readings`` setting: ``error`` makes
our readings errors too (a QA lead who adopts them); information stays a notice. A code's first row is
its plain rule (``RULES[code]``), used where a violation names no rule of its own (the frame table).
docs/protocol.md "Violation codes" is generated from these rows (``docgen``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, Literal

from . import spec

BasisKind = Literal["stated", "reading", "information"]
Readings = Literal["notice", "error"]
READINGS: Final[tuple[Readings, ...]] = ("notice", "error")
DEFAULT_READINGS: Final[Readings] = "notice"


@dataclass(frozen=True)
class Basis:
    """Where a rule comes from: ``kind``; ``where``: a vendor section (``§6``) or a silent item of
    docs/protocol.md; ``words``: the vendor text's own words (Japanese) and what they say, or what the
    text leaves open."""

    kind: BasisKind
    where: str
    words: str

    def show(self) -> str:
        if self.kind == "stated":
            return f"vendor {self.where}: {self.words}"
        label = "our reading" if self.kind == "reading" else "information"
        return f"{label} ({self.where}): {self.words}"


@dataclass(frozen=True)
class Rule:
    """One rule: its name, the violation code it reports, what it checks and its basis."""

    name: str
    code: spec.ViolationCode
    checks: str
    basis: Basis

    @property
    def severity(self) -> spec.Severity:
        """Derived from the basis: a rule the vendor text states is an error; anything else a notice."""
        return spec.ERROR if self.basis.kind == "stated" else spec.NOTICE

    @property
    def duty(self) -> spec.Duty:
        return spec.VIOLATION_TABLE[self.code].duty


def _stated(where: str, words: str) -> Basis:
    return Basis("stated", where, words)


def _reading(where: str, words: str) -> Basis:
    return Basis("reading", where, words)


def _info(where: str, words: str) -> Basis:
    return Basis("information", where, words)


_ANSWER_DEF: Final = ("「アンサー: コマンドを受けたコントローラが上位機器に送るデータ」 "
                       "(an answer is what the controller sends on receiving a command)")
_ERROR_CODE: Final = ("「通信からの命令でエラーが発生したときはエラーコードで応答します」 "
                       "(an error in a command from the line is answered with an error code)")
_LATCH: Final = ("「アラームリセット命令があるまでアラームを保持し、"
                  "他のコマンドに対してもアラームアンサーを返信します」 "
                  "(the alarm is held until an alarm reset and other commands get the alarm answer too)")
_RESET_WORDS: Final = "「非常停止以外のアラームのリセットを行います」 (resets every alarm but emergency stop)"
_CAUTION: Final = ("「正しいコマンドを送っているにもかかわらず、アラームが返信される場合は、"
                   "上位機器、ケーブル、…のいずれかに異常がある可能性があります」 "
                   "(an alarm to a correct command may be the host's or the cable's fault)")
_MOTION: Final = ("「0MVコマンド受信後はアンサーを送信するまで通信できません」 "
                  "(after 0MV no communication until its answer)")

# The rulebook, one row a rule; a code's first row is its plain rule. Order: the report order of the codes.
RULE_ROWS: Final[tuple[Rule, ...]] = (
    Rule("bad-length", "bad-length", "the frame's byte count is the spec's, CR LF included",
         _stated("§5", "「送信・受信のバイト数は、CR・LFも含まれます」 (byte counts include CR LF)")),
    Rule("bad-terminator", "bad-terminator", "a frame ends with CR LF",
         _stated("§5", "「コマンドの最終データはCR・LFです」 (a command's last data is CR LF)")),
    Rule("letter-o", "letter-o", "a command starts with the digit 0",
         _stated("§5", "「各コマンドの先頭の文字は“ゼロ”です」 (each command's first character is zero)")),
    Rule("letter-o-answer", "letter-o", "an answer starts with the digit 0",
         _reading("silent item 21", "§5 states the leading zero of commands only; its own tables write "
                  "answers with the letter O (ORP, ORC)")),
    Rule("lowercase-hex", "lowercase-hex", "hex digits and headers in upper case",
         _info("silent item 2", "the vendor writes upper case and says nothing of lower case")),
    Rule("missing-2", "missing-2", "the mandatory character 2",
         _stated("§7 (1)-(8)", "「必ず8文字目には2が入ります」 (the 8th character is always 2)")),
    Rule("field-range", "field-range", "a field within its range",
         _stated("§2", "「設定範囲」 (the range of N, V, A, O, Pos)")),
    Rule("0wc-point-0", "field-range", "0WC with N 0",
         _reading("silent item 4", "§2 gives N the range 0~F and §7 (4) sets 0WC no narrower one (0RP and "
                  "0WP say 1~F)")),
    Rule("version-digits", "field-range", "0RV's ver as three decimal digits",
         _reading("silent item 21", "「ver: バージョン情報」 (version information): only the example "
                  "0RV100 for version 1.00 shows three digits")),
    Rule("unknown-command", "unknown-command", "a header of the command list",
         _stated("§5", "the command list 「コマンド一覧」 and §6's alarm answer and reset")),
    Rule("garbage", "garbage", "bytes form frames",
         _stated("§5", "「コマンドの最終データはCR・LFです」 with the frame layouts of §6 and §7")),
    Rule("echo-mismatch", "echo-mismatch", "an echo answer carries its command's fields",
         _stated("§7 (2), (6), (8), (10)", "「コマンドと同じ内容が返信されます」 (the same content as the "
                 "command is returned; 0WP: the write's result)")),
    Rule("answer-mismatch", "answer-mismatch", "the answer is the command's, for its N",
         _stated("§2", _ANSWER_DEF)),
    Rule("unsolicited-answer", "unsolicited-answer", "an answer answers a command",
         _stated("§2", _ANSWER_DEF)),
    Rule("no-answer", "no-answer", "a command gets its answer (within the window of silent item 17)",
         _stated("§2", _ANSWER_DEF)),
    Rule("no-answer-error", "no-answer", "a command with an error gets an alarm answer",
         _stated("§5", _ERROR_CODE)),
    Rule("no-answer-junk", "no-answer", "a host line that is no command gets an alarm answer",
         _reading("silent item 1", "§5 gives an error code to an error in a command; a line that is no "
                  "command is not stated")),
    Rule("late-move-answer", "no-answer", "a move's answer comes within twice its time estimated from the "
         "guessed speed table (a table the user gives makes that window the plain no-answer rule)",
         _reading("silent items 15, 17", "the vendor text gives no speed table and no time for a move's "
                  "answer (§7 (5), (6): no communication until the answer): a window estimated from a "
                  "guessed table is ours")),
    Rule("overlapping-command", "overlapping-command", "one command at a time: the next after the answer",
         _stated("§2, §7 (6)", f"{_ANSWER_DEF}; {_MOTION}")),
    Rule("command-during-motion", "command-during-motion", "no command while a move's answer is awaited",
         _stated("§7 (6)", _MOTION)),
    Rule("alarm-ignored", "alarm-ignored", "the host resets an alarm before going on",
         _reading("\"Behaviour\": latch", f"§6 {_LATCH}: the device's duty; no host duty is stated")),
    Rule("comm-error-storm", "comm-error-storm", "the host stops after a run of communication errors",
         _stated("§6 caution", "「通信エラーが連続して（例えば5回以上）返信された時は、"
                 "動作を停止するような機構を設け」 (after communication errors in a row, e.g. 5 or more, "
                 "stop)")),
    Rule("storm-recovery", "storm-recovery", "recovering from a storm with an alarm reset",
         _reading("\"Behaviour\": host duty", "§6's caution asks to stop and check the equipment; a reset "
                  "after it is not forbidden")),
    Rule("error-accepted", "error-accepted", "an error is answered with an alarm answer",
         _stated("§5", _ERROR_CODE)),
    Rule("latch-broken", "latch-broken", "a normal answer never comes while an alarm is latched",
         _stated("§6", _LATCH)),
    Rule("latch-code-changed", "latch-broken", "a latched alarm answered with another code (not 0E)",
         _reading("silent item 22", f"§6 does not say which code wins when a new error arrives under a "
                  f"latch, and its caution says {_CAUTION}")),
    Rule("reset-refused", "latch-broken", "an alarm reset (0%C) answered with an alarm other than 0E",
         _reading("silent item 22", f"§6 {_RESET_WORDS}, but the reset line itself may arrive garbled: "
                  f"{_CAUTION}")),
    Rule("stop-alarm-back", "latch-broken", "the alarm a reset cleared during the emergency stop does "
         "not come back, one held under it is not forgotten", _reading("silent item 3", "the vendor text "
                                                                      "says nothing of the release")),
    Rule("estop-cleared", "estop-cleared", "an alarm reset does not clear emergency stop",
         _stated("§6", _RESET_WORDS)),
    Rule("readback-mismatch", "readback-mismatch", "a point reads back as written, stored or read",
         _stated("§7 (1), (2), (4)", "「位置番号Nの移動データを返信します」「移動データを設定します」 "
                 "(0RP returns point N's data; 0WP sets it)")),
    Rule("readback-outputs", "readback-mismatch", "the OUT ports read back as written or read",
         _stated("§7 (7), (8)", "「現在の出力ポートの状態を返信します」 (0RS returns the OUT ports' state; "
                 "0WS sets it)")),
    Rule("readback-position", "readback-mismatch", "the position reads back where a move went",
         _stated("§7 (3), (5), (6)", "「現在位置を返信します」「位置番号Nに移動します」 "
                 "(0RC returns the current position; 0MP and 0MV move there)")),
    Rule("readback-unhomed", "readback-mismatch", "0RC before homing answers N, V, A 0 and Pos FFFFFF",
         _stated("§7 (3)", "「原点復帰および移動していない場合、N, V, Aには0、POSにはFFFFFFが入ります」 (not "
                 "homed: N, V, A 0 and Pos FFFFFF)")),
    Rule("readback-version", "readback-mismatch", "the version reads back the same",
         _reading("silent item 22", "§7 (9) 「コントローラのバージョン情報を返信します」 says nothing of it "
                  "changing within a conversation")),
    Rule("reserved-alarm", "reserved-alarm", "alarm codes with a meaning",
         _info("silent item 13", "§6 lists 02, 03, 05, 07 with no meaning")),
    Rule("unknown-alarm", "unknown-alarm", "alarm codes of the vendor's list",
         _info("§6", "the alarm list 「アラーム一覧」 does not hold the code")),
)

RULES: Final[dict[str, Rule]] = {r.name: r for r in RULE_ROWS}
assert len(RULES) == len(RULE_ROWS), "rule names are unique"
assert {r.code for r in RULE_ROWS} == set(spec.VIOLATION_TABLE), "every code has a rule"
assert all(r.code in RULES for r in RULE_ROWS), "every code has its plain rule (named after it)"
assert all(RULES[v.code].severity == v.severity for v in spec.VIOLATION_SPECS), \
    "a code's severity in spec.VIOLATION_SPECS is its plain rule's"

# severity of every rule under each readings setting (looked up once a violation)
_SEVERITIES: Final[dict[Readings, dict[str, spec.Severity]]] = {
    "notice": {r.name: r.severity for r in RULE_ROWS},
    "error": {r.name: spec.ERROR if r.basis.kind == "reading" else r.severity for r in RULE_ROWS},
}


READINGS_HELP: Final = ("the severity of the rules that are our reading of a silent vendor text: notice "
                        "(default) or error, for a QA lead who adopts them "
                        "(docs/protocol.md \"Violation codes\")")


def severity(rule: str, readings: Readings = DEFAULT_READINGS) -> spec.Severity:
    """The severity of ``rule`` under ``readings`` (module docstring)."""
    return _SEVERITIES[readings][rule]


def severities(readings: Readings = DEFAULT_READINGS) -> dict[str, spec.Severity]:
    """Rule name -> severity under ``readings`` (a table to look violations up in)."""
    return _SEVERITIES[readings]
