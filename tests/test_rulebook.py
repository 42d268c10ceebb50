"""The rulebook as data (issue 35): each rule's severity follows its basis, and the verdicts the vendor
text does not support are put right. Each ``test_verdict_*`` is named after the rule it holds and failed
on the engine before the fix (the issue's "Verdicts to put right", numbered as there)."""

from __future__ import annotations

import re

import pytest
from conftest import budget
from hypothesis import given, settings
from hypothesis import strategies as st
from test_conversation_unseen import talk  # command and answer pairs 0.1 s apart

from xac1_proto import docgen, motion, rules, spec
from xac1_proto.codec import read_frame
from xac1_proto.conversation import LEARNT, UNKNOWN, Conversation, Verdict


def codes(verdicts: list[Verdict]) -> list[str]:
    return [code for v in verdicts for code in v.codes]


def errors(verdicts: list[Verdict]) -> list[str]:
    """The codes of the violations that fail a device or a host (notices left out)."""
    return [e.code for v in verdicts for e in v.errors]


# ---- 1. a latched alarm answered with another code ----

def test_verdict_latch_code_changed_is_a_notice():
    """A malformed line's 01 while 08 is held is reported (latch-broken) but as a notice: §6 does not say
    which code wins under a latch (silent item 22)."""
    verdicts, _ = talk((b"0MP5\r\n", b"0%%08\r\n"), (b"0%C\r\n", b"0%C00\r\n"), (b"0MP5\r\n", b"0%%08\r\n"),
                       (b"0RP\r\n", b"0%%01\r\n"))
    assert "latch-broken" in codes(verdicts)
    assert "latch-broken" not in errors(verdicts)


def test_verdict_reset_refused_is_a_notice():
    """0%C answered 0%%01 (the reset line may itself have arrived garbled, §6 caution): a notice."""
    verdicts, _ = talk((b"0MP5\r\n", b"0%%08\r\n"), (b"0%C\r\n", b"0%%01\r\n"))
    assert "latch-broken" in codes(verdicts)
    assert "latch-broken" not in errors(verdicts)


def test_a_normal_answer_under_a_latch_stays_an_error():
    """§6 states it: the alarm is held until a reset and other commands get the alarm answer."""
    verdicts, _ = talk((b"0MP5\r\n", b"0%%08\r\n"), (b"0RV\r\n", b"0RV100\r\n"))
    assert "latch-broken" in errors(verdicts)


# ---- 2. 0WC0 ----

@pytest.mark.parametrize("answer", [b"0WC00302001000\r\n", b"0%%01\r\n"])
def test_verdict_0wc_point_0_is_no_error(answer):
    """0WC with N 0: §2's N is 0~F and §7 (4) sets no narrower range. Neither a normal answer
    (error-accepted before) nor an alarm is judged; the host's N 0 is a field-range notice."""
    verdicts, _ = talk((b"0WC0\r\n", answer))
    assert errors(verdicts) == []
    assert codes(verdicts)[0] == "field-range"
    assert "error-accepted" not in codes(verdicts)


# ---- 3. OUT ports after an emergency stop and after FFFFFF ----

def test_verdict_outputs_unknown_after_an_emergency_stop():
    """The text says nothing of the OUT ports across an emergency stop: unknown until read."""
    verdicts, c = talk((b"0WS12\r\n", b"0WS12\r\n"), (b"0RV\r\n", b"0%%0E\r\n"), (b"0%C\r\n", b"0%C00\r\n"),
                       (b"0RS\r\n", b"0RS02\r\n"))
    assert "readback-mismatch" not in codes(verdicts)
    assert (c.knowledge.outputs.value, c.knowledge.outputs.status) == (0, LEARNT)


def test_verdict_outputs_unknown_after_ffffff():
    """0RC answering FFFFFF may be an unseen power cycle: the OUT ports are unknown until read."""
    verdicts, _ = talk((b"0WS12\r\n", b"0WS12\r\n"), (b"0RC\r\n", b"0RC00002FFFFFF\r\n"),
                       (b"0RS\r\n", b"0RS02\r\n"))
    assert codes(verdicts) == []


def test_verdict_outputs_unknown_after_the_stop_input():
    """With the stop input fed, the OUT ports are unknown after the stop too."""
    c = Conversation()
    talk((b"0WS12\r\n", b"0WS12\r\n"), c=c)
    c.stop_input(True)
    c.stop_input(False)
    assert c.knowledge.outputs.status == UNKNOWN


# ---- 4. homed after a power-on or after learning "not homed" ----

def test_verdict_readback_unhomed_not_judged_in_mode_0():
    """After power-on the controller is in mode 0 (§7 (10)), where the external I/O may home the axis:
    0RC answering a position is learnt."""
    c = Conversation()
    c.power_on()
    verdicts, c = talk((b"0RC\r\n", b"0RC00002000100\r\n"), c=c)
    assert codes(verdicts) == []
    assert c.knowledge.homed.value is True


# ---- 6. the alarm a reset cleared during the stop is forgotten once answered normally ----

def test_verdict_stop_alarm_back_forgotten_after_a_normal_answer():
    """Stop input fed: 01 latched, stop, reset during the stop clears 01, release. After a normal answer a
    new 01 much later is a new alarm, not latch-broken."""
    c = Conversation()
    out = c.host_frame(b"0RP\r\n", 0.0, 0.0) + c.device_frame(b"0%%01\r\n", 0.01, 0.01)
    c.stop_input(True)
    out += c.host_frame(b"0%C\r\n", 0.1, 0.1) + c.device_frame(b"0%%0E\r\n", 0.11, 0.11)
    c.stop_input(False, unhomes=True)
    out += c.host_frame(b"0RV\r\n", 0.2, 0.2) + c.device_frame(b"0RV100\r\n", 0.21, 0.21)
    out += c.host_frame(b"0RS\r\n", 5.0, 5.0) + c.device_frame(b"0RS02\r\n", 5.01, 5.01)
    out += c.host_frame(b"0RV\r\n", 60.0, 60.0) + c.device_frame(b"0%%01\r\n", 60.01, 60.01)
    assert "latch-broken" not in codes(out)


# ---- 7. FFFFFF with N, V or A not 0 ----

def test_verdict_readback_unhomed_ffffff_with_nva_not_0():
    """§7 (3): not homed, N, V, A are 0 with Pos FFFFFF, whatever else is known (no power_on needed)."""
    verdicts, _ = talk((b"0RC\r\n", b"0RC31002FFFFFF\r\n"))
    assert errors(verdicts) == ["readback-mismatch"]


# ---- 8. a host junk line left unanswered ----

@pytest.mark.parametrize("junk", [b"\r\n", b"\x00\xff~\n"])
def test_verdict_no_answer_junk_is_a_notice(junk):
    """§5 gives an error code to an error in a command; a line that is no command is not stated."""
    c = Conversation()
    out = c.host_junk(junk, 0.0, 0.0) + c.close(5.0)
    assert [v.kind for v in out] == ["host-junk", "no-answer"]
    assert codes(out) == ["garbage", "no-answer"]
    assert "no-answer" not in errors(out)


def test_a_malformed_command_left_unanswered_stays_an_error():
    """§5 states it: an error in a command is answered with an error code."""
    c = Conversation()
    out = c.host_frame(b"0RP\r\n", 0.0, 0.0) + c.close(5.0)
    assert "no-answer" in errors(out)


# ---- 9. the answers' leading 0, ver's digits, true bases ----

def test_verdict_letter_o_answer_is_a_notice():
    """§5 states the leading zero of commands only: an answer with the letter O is a notice."""
    verdicts, _ = talk((b"0RV\r\n", b"ORV100\r\n"))
    assert codes(verdicts) == ["letter-o"] and errors(verdicts) == []
    command = read_frame(b"ORV\r\n", spec.COMMAND)
    assert command.error and command.violations[0].severity == spec.ERROR


def test_verdict_version_digits_is_a_notice():
    """ver is "version information": three decimal digits only in the example. Decoded, a notice."""
    verdicts, c = talk((b"0RV\r\n", b"0RV1.0\r\n"))
    assert codes(verdicts) == ["field-range"] and errors(verdicts) == []
    assert c.knowledge.version.value == "1.0"


def test_verdict_readback_version_is_a_notice():
    """Nothing says the version cannot change within a conversation (silent item 22)."""
    verdicts, _ = talk((b"0RV\r\n", b"0RV100\r\n"), (b"0RV\r\n", b"0RV101\r\n"))
    assert codes(verdicts) == ["readback-mismatch"] and errors(verdicts) == []


def test_every_rule_has_its_true_basis():
    """A stated rule cites a vendor section with the text's own (Japanese) words; a reading or
    information cites a silent item or a docs/protocol.md section; no basis is the generic "Behaviour"
    section alone (readback-mismatch and no-answer were filed under it)."""
    for r in rules.RULE_ROWS:
        if r.basis.kind == "stated":
            assert r.basis.where.startswith("§"), r.name
            assert re.search(r"[\u3040-\u30ff\u4e00-\u9fff]", r.basis.words), r.name
        else:
            assert r.basis.where.startswith(("silent item", "\"Behaviour\"", "§")), r.name
        assert r.severity == (spec.ERROR if r.basis.kind == "stated" else spec.NOTICE)
    assert rules.RULES["no-answer-junk"].severity == spec.NOTICE
    assert rules.RULES["readback-version"].severity == spec.NOTICE


def test_the_doc_table_is_the_rulebook():
    """docs/protocol.md's violation table is the rule rows, each with its severity and basis."""
    page = docgen.DEFAULT_PATH.read_text(encoding="utf-8")
    assert docgen.update(page) == page
    block = page.split("<!-- generated: violations -->")[1].split(docgen.END)[0]
    rows = [line for line in block.splitlines() if line.startswith("| `")]
    assert len(rows) == len(rules.RULE_ROWS)
    for line, r in zip(rows, rules.RULE_ROWS, strict=True):
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[:3] == [f"`{r.code}`", r.name, r.severity]
        assert cells[-1] == r.basis.show()


# ---- --readings error ----

def test_readings_error_makes_readings_errors():
    """``readings="error"``: the rules that are our reading fail too; information stays a notice."""
    script = ((b"0RV\r\n", b"ORV100\r\n"), (b"0rv\r\n", b"0RV100\r\n"), (b"0WC0\r\n", b"0%%01\r\n"))
    lenient, _ = talk(*script)
    strict, _ = talk(*script, c=Conversation(readings="error"))
    assert errors(lenient) == []
    assert errors(strict) == ["letter-o", "field-range"]  # lowercase-hex: information, a notice
    with pytest.raises(ValueError, match="readings"):
        Conversation(readings="strict")  # type: ignore[arg-type]


EXCHANGES = st.sampled_from([
    (b"0MP5\r\n", b"0%%08\r\n"), (b"0RP\r\n", b"0%%01\r\n"), (b"0%C\r\n", b"0%C00\r\n"),
    (b"0%C\r\n", b"0%%01\r\n"), (b"0RV\r\n", b"ORV100\r\n"), (b"0RV\r\n", b"0RV101\r\n"),
    (b"0WC0\r\n", b"0WC00302001000\r\n"), (b"0RC\r\n", b"0RC31002FFFFFF\r\n"), (b"0WS12\r\n", b"0WS12\r\n"),
    (b"0RS\r\n", b"0RS02\r\n"), (b"0RV\r\n", None), (b"0rs\r\n", b"0RS12\r\n")])


@settings(max_examples=budget(60), deadline=None)
@given(st.lists(EXCHANGES, max_size=10))
def test_readings_set_every_severity(pairs):
    """Over any conversation, each violation's severity is its rule's under the ``readings`` setting (so
    under ``error`` only information is a notice), and the verdict's ``severities`` align with ``codes``,
    ``error`` where any violation of the code is one."""
    notice, _ = talk(*pairs)
    error, _ = talk(*pairs, c=Conversation(readings="error"))
    for verdicts, readings in ((notice, "notice"), (error, "error")):
        for v in verdicts:
            assert len(v.severities) == len(v.codes)
            for code, severity in zip(v.codes, v.severities, strict=True):
                worst = {x.severity for x in v.violations if x.code == code}
                assert severity == (spec.ERROR if spec.ERROR in worst else spec.NOTICE)
            for x in v.violations:
                assert x.severity == rules.severity(x.rule, readings)  # type: ignore[arg-type]
                assert rules.RULES[x.rule].code == x.code
                if readings == "error" and not x.is_error:
                    assert rules.RULES[x.rule].basis.kind == "information"


def test_conformance_verdict_junit_and_html_say_the_readings():
    """The conformance verdict line, the JUnit properties and the HTML report say which ``--readings``
    setting judged the device."""
    import xml.etree.ElementTree as ET

    from conformance.junit import junit_tree
    from conformance.report import Report, html_page

    for readings in rules.READINGS:
        rep = Report(port="socket://127.0.0.1:1", version="100", date="2026-01-01 00:00:00 UTC",
                     options=[("port", "x")], checks=[], infos=[], info_errors=[], timing=[], safety=[],
                     safety_problems=[], abort=None, command_line="xac1 conformance", readings=readings)
        assert f"; readings: {readings}" in rep.verdict_line
        props = {p.get("name"): p.get("value") for p in junit_tree(rep).getroot().iter("property")}
        assert props["readings"] == readings
        assert f"readings: {readings}" in html_page(rep)
        assert ET.tostring(junit_tree(rep).getroot())  # still a well-formed tree


@pytest.mark.slow  # two processes
def test_decode_readings_option_sets_the_severities():
    """``xac1 decode --readings error`` makes our readings (alarm-ignored here) errors in JSON lines and a
    ✗ in the text view; the default keeps them notices ("!")."""
    import json

    from conftest import xac1

    def severities(*options: str) -> dict[str, set[str]]:
        out = xac1("decode", "captures/socat-xv.log", "--format", "jsonl", *options)
        assert out.returncode in (0, 1), out.stderr
        seen: dict[str, set[str]] = {}
        for line in out.stdout.splitlines()[:-1]:
            r = json.loads(line)
            for code, severity in zip(r["violations"], r["severities"], strict=True):
                seen.setdefault(code, set()).add(severity)
        return seen

    assert severities()["alarm-ignored"] == {"notice"}
    assert severities("--readings", "error")["alarm-ignored"] == {"error"}
    text = xac1("decode", "captures/socat-xv.log", "--readings", "error", "--no-color").stdout
    assert "host   ✗ alarm-ignored" in text
    bad = xac1("decode", "captures/socat-xv.log", "--readings", "strict")
    assert bad.returncode == 2 and "--readings" in bad.stderr


def test_every_rule_row_is_applied():
    """No row documents a rule the engine does not apply: every rule that is not a code's plain rule is
    named where a violation is made (the decoder or the engine)."""
    from pathlib import Path

    import xac1_proto

    root = Path(xac1_proto.__file__).parent
    source = (root / "conversation.py").read_text(encoding="utf-8") + (root / "codec.py").read_text(
        encoding="utf-8")
    for r in rules.RULE_ROWS:
        assert r.name == r.code or f'"{r.name}"' in source, r.name


# ---- the latch's state machine (issue 35, item 2) ----

def test_the_latch_table_and_the_doc_rule_table_say_the_same():
    """Every rule a cell of the latch's state machine (``latch.LATCH``, ``latch.HOST_DUTY``) names is a row
    of the rulebook and of docs/protocol.md's violation table; every rule of the latch's codes
    (latch-broken, estop-cleared, the storm's) is named by a cell; and the page's latch table is the
    declared one, cell for cell."""
    from xac1_proto import latch

    page = docgen.DEFAULT_PATH.read_text(encoding="utf-8")
    violations = page.split("<!-- generated: violations -->")[1].split(docgen.END)[0]
    doc_rules = {cells[1].strip(): cells[0].strip(" `") for cells in
                 (line.strip("|").split("|") for line in violations.splitlines() if line.startswith("| `"))}
    named = latch.rules_named()
    assert named <= set(doc_rules) and named <= set(rules.RULES)
    latch_codes = {"latch-broken", "estop-cleared", "comm-error-storm", "storm-recovery"}
    assert {r.name for r in rules.RULE_ROWS if r.code in latch_codes} == named
    block = page.split("<!-- generated: latch -->")[1].split(docgen.END)[0]
    rows = [line for line in block.splitlines() if line.startswith("| ") and not line.startswith("| event")]
    assert len(rows) == len(latch.LatchEvent)
    for line, event in zip(rows, latch.LatchEvent, strict=True):
        cells = [c.strip() for c in line.strip("|").split("|")]
        for cell, state in zip(cells[1:], latch.LatchState, strict=True):
            rule = latch.LATCH[(state, event)].rule
            assert cell.split(" → ")[0] == (f"`{rule}`" if rule else "-")


@pytest.mark.parametrize(("script", "state"), [
    ((), "FREE"),
    (((b"0RV\r\n", b"0%%08\r\n"),), "HELD"),
    (((b"0RV\r\n", b"0%%0E\r\n"),), "STOP_UNSEEN"),
    (((b"0RV\r\n", b"0%%08\r\n"), (b"0RV\r\n", b"0%%0E\r\n")), "STOP_UNSEEN_OVER"),
])
def test_the_latch_state_is_read_from_what_the_line_showed(script, state):
    """``Conversation.latch_state``: nothing latched, an alarm latched, 0E with the stop input unseen (it
    may have been released), and 0E over an alarm held under it until a reset (vendor §6; silent item 3)."""
    _, c = talk(*script)
    assert c.latch_state().name == state


def test_the_stop_input_known_pressed_is_the_stop_state():
    """A caller that drives the stop input: pressed, 0E latches with the input known pressed (STOP); a
    reset then answered 0%C00 is ``estop-cleared`` in every state (vendor §6: the reset clears every
    alarm but emergency stop)."""
    c = Conversation()
    c.stop_input(True)
    assert c.latch_state().name == "STOP"
    out = c.host_frame(b"0%C\r\n", 0.0, 0.0) + c.device_frame(b"0%C00\r\n", 0.01, 0.01)
    assert codes(out) == ["estop-cleared"] and c.knowledge.latched.value == spec.ALARM_ESTOP


# ---- 5. move answer windows from a guessed speed table ----

FIRST_MOVE, MOVE = b"0MV3C3001000\r\n", b"0MV3C3002000\r\n"


def _late_move(c: Conversation, late_by: float, then: tuple[bytes, bytes] | None = None) -> list[Verdict]:
    """A move to a known start, then a second move whose answer comes ``late_by`` s after its window
    (the window the engine gives it, from its speed table); ``then``: another exchange after that."""
    out = c.host_frame(FIRST_MOVE, 0.0, 0.0) + c.device_frame(FIRST_MOVE, 1.0, 1.0)
    window = c.answer_window(read_frame(MOVE, spec.COMMAND).frame)
    out += c.host_frame(MOVE, 2.0, 2.0)
    answer_at = 2.0 + window + late_by
    if then is not None:
        out += c.host_frame(then[0], answer_at - 0.01, answer_at - 0.01)
    out += c.tick(answer_at - 0.001) + c.device_frame(MOVE, answer_at, answer_at)
    if then is not None:
        out += c.device_frame(then[1], answer_at + 0.01, answer_at + 0.01)
    return out + c.close()


def test_verdict_late_move_answer_is_a_notice():
    """A move's answer later than its window, which rests only on the guessed speed table (silent items
    15, 17), is paired with its move and is a ``no-answer`` notice (rule ``late-move-answer``), never a
    ``no-answer`` and ``unsolicited-answer`` pair of errors."""
    verdicts = _late_move(Conversation(), late_by=5.0)
    answer = [v for v in verdicts if v.kind == "device-frame"][-1]
    assert codes(verdicts) == ["no-answer"] and errors(verdicts) == []
    assert answer.reply_to == 2 and answer.violations[0].rule == "late-move-answer"
    assert answer.severities == ("notice",)


def test_a_move_answer_in_its_guessed_window_is_clean():
    """Within the window estimated from the guessed table, a move's answer is in time."""
    assert codes(_late_move(Conversation(), late_by=-0.5)) == []


def test_a_late_move_answer_under_readings_error_is_an_error():
    """``--readings error`` adopts the guessed window: the late answer is an error (still paired)."""
    verdicts = _late_move(Conversation(readings="error"), late_by=5.0)
    assert errors(verdicts) == ["no-answer"]
    assert [v.reply_to for v in verdicts if v.kind == "device-frame"] == [0, 2]


def test_a_late_move_whose_answer_never_comes_is_no_answer():
    """A late move the device never answers is ``no-answer`` (an error, vendor §2) when the data ends or
    the device answers a later line instead."""
    c = Conversation()
    c.host_frame(FIRST_MOVE, 0.0, 0.0) + c.device_frame(FIRST_MOVE, 1.0, 1.0)
    out = c.host_frame(MOVE, 2.0, 2.0) + c.close(100.0)
    assert errors(out) == ["no-answer"]
    c = Conversation()
    c.host_frame(FIRST_MOVE, 0.0, 0.0) + c.device_frame(FIRST_MOVE, 1.0, 1.0)
    after = 2.0 + c.answer_window(read_frame(MOVE, spec.COMMAND).frame) + 1.0
    out = c.host_frame(MOVE, 2.0, 2.0) + c.host_frame(b"0RV\r\n", after, after)
    out += c.device_frame(b"0RV100\r\n", after + 0.01, after + 0.01) + c.close()
    assert errors(out) == ["no-answer"] and [v.reply_to for v in out if v.kind == "no-answer"] == [2]


def test_a_late_move_answer_after_another_exchange_is_still_its_answer():
    """The host went on after the guessed window closed; the move's late answer, before the next
    command's, is still the move's (a notice), the next command's answer its own."""
    verdicts = _late_move(Conversation(), late_by=5.0, then=(b"0RV\r\n", b"0RV100\r\n"))
    assert codes(verdicts) == ["no-answer"] and errors(verdicts) == []
    assert [v.reply_to for v in verdicts if v.kind == "device-frame"] == [0, 2, 3]


def test_a_speed_table_the_user_gives_makes_the_window_firm():
    """With the device's speed table given (``--speed-table``), a move's window no longer rests on a
    guess: an answer later than it is ``no-answer`` and the answer is ``unsolicited-answer``, errors as
    for any command (docs/protocol.md silent item 17)."""
    speeds = motion.SpeedTable.parse("1000:500:10000")
    verdicts = _late_move(Conversation(speeds=speeds), late_by=5.0)
    assert errors(verdicts) == ["no-answer", "unsolicited-answer"]


@pytest.mark.parametrize(("text", "wrong"), [("1000:500", "V:VEL:HOMING"), ("a:b:c", "numbers"),
                                             ("1000:0:10000", "positive"), ("1:1:1:7", "acceleration")])
def test_a_bad_speed_table_is_refused_naming_what_is_wrong(text, wrong):
    """``--speed-table`` refuses a table it cannot use, saying what was wrong."""
    with pytest.raises(ValueError, match=wrong):
        motion.SpeedTable.parse(text)


@pytest.mark.slow
def test_decode_speed_table_option_makes_the_move_window_firm(tmp_path):
    """``xac1 decode`` without ``--speed-table``: a move answered later than its guessed window is paired
    with its move, a ``no-answer`` notice; with the device's table given, the same answer is
    ``no-answer`` and ``unsolicited-answer`` errors (silent items 15, 17)."""
    import json

    from conftest import xac1

    from xac1_proto.chunk import Chunk
    from xac1_proto.recording import RecordingWriter

    c = Conversation()
    c.host_frame(FIRST_MOVE, 0.0, 0.0) + c.device_frame(FIRST_MOVE, 1.0, 1.0)
    late = 2.0 + c.answer_window(read_frame(MOVE, spec.COMMAND).frame) + 5.0
    path = tmp_path / "late.jsonl"
    with RecordingWriter(path, started=0.0) as w:
        for t, side, data in [(0.0, "host", FIRST_MOVE), (1.0, "device", FIRST_MOVE), (2.0, "host", MOVE),
                              (late, "device", MOVE)]:
            w.write(Chunk(1000.0 + t, side, data))

    def judged(*options: str) -> list[tuple[str, str]]:
        out = xac1("decode", str(path), "--format", "jsonl", *options)
        assert out.returncode in (0, 1), out.stderr
        records = [json.loads(line) for line in out.stdout.splitlines()[:-1]]
        return [(code, sev) for r in records for code, sev in zip(r["violations"], r["severities"],
                                                                  strict=True)]

    assert judged() == [("no-answer", "notice")]
    assert judged("--speed-table", "1000:500:10000") == [("no-answer", "error"),
                                                         ("unsolicited-answer", "error")]
    bad = xac1("decode", str(path), "--speed-table", "fast")
    assert bad.returncode == 2 and "argument --speed-table: expected V:VEL:HOMING" in bad.stderr  # named once
