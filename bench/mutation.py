"""The figures of ``make mutate`` (issue 35): per safety module, the mutants mutmut made, the share the
fast tests killed, and every survivor, the equivalent ones (``EQUIVALENT``: no test can tell them from
the original; why is given) apart from the rest. Reads mutmut's results under ``mutants/``; run from the
repository's root after ``mutmut run``. Exits 1 when a survivor is not named equivalent.

    python bench/mutation.py            # the table and the survivors
"""

from __future__ import annotations

import ast
import json
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: mutmut's exit codes: 1 and 3 a test failed (killed); a timeout (the mutant hangs the tests) is
#: counted as killed too (pytest-timeout would fail it); 0 survived; 5 and 33 no test covers it.
KILLED, TIMEOUT, SURVIVED, NO_TESTS = {1, 3}, {24, -24, 36, 152, 255}, {0}, {5, 33}

#: Survivors no test can kill: the mutant behaves as the original on every input the code can get.
#: Each name with the line the mutant changes (as ``changed_lines`` reads it) and why it is equivalent.
EQUIVALENT: dict[str, tuple[str, str]] = {
    'ribbond.gcode.checker.x__feed_text__mutmut_12':
        ('return f"{math.floor(feed * 10 + 1e-6) / 10:.1f}".rstrip("XX0XX").rstrip(".")',
         'rstrip("0")/rstrip(".") gain "X" in the set stripped: a number never ends in X'),
    'ribbond.gcode.checker.x__feed_text__mutmut_13':
        ('return f"{math.floor(feed * 10 + 1e-6) / 10:.1f}".rstrip("0").rstrip("XX.XX")',
         'rstrip("0")/rstrip(".") gain "X" in the set stripped: a number never ends in X'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_43':
        ('return _with_feed(command, f"{m.feed:.3f}".rstrip("XX0XX").rstrip("."))',
         'likewise: rstrip of a formatted number gains "X"'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_44':
        ('return _with_feed(command, f"{m.feed:.3f}".rstrip("0").rstrip("XX.XX"))',
         'likewise: rstrip of a formatted number gains "X"'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁcheck__mutmut_11':
        ('command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).split("*", )[0].strip()',
         'split("*") with another maxsplit: the part before the first "*" is the same'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁcheck__mutmut_20':
        ('command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).split("*", 2)[0].strip()',
         'split("*") with another maxsplit: the part before the first "*" is the same'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_19':
        ('command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).split("*", )[0].strip()',
         'the checksum cut before GcodeChecker.command, which cuts it again the same way'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_20':
        ('command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).rsplit("*", 1)[0].strip()',
         'the checksum cut before GcodeChecker.command, which cuts it again the same way'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_27':
        ('command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).split("XX*XX", 1)[0].strip()',
         'the checksum cut before GcodeChecker.command, which cuts it again the same way'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_28':
        ('command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).split("*", 2)[0].strip()',
         'the checksum cut before GcodeChecker.command, which cuts it again the same way'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_move__mutmut_13':
        ('if letter not in "XXXYZEFXX" or value is None:',
         '"XYZEF"/"XYZ" -> "XXXYZEFXX"/"XXXYZXX": the same set of one-letter words'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_move__mutmut_31':
        ('if any(a in args for a in "XXXYZXX"):',
         '"XYZEF"/"XYZ" -> "XXXYZEFXX"/"XXXYZXX": the same set of one-letter words'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_end__mutmut_22':
        ('if any(a in args for a in "XXXYZXX") and any(v is None for v in end):',
         '"XYZ" -> "XXXYZXX": the same set of one-letter words'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_21':
        ('m.sent_feed = None',
         'sent_feed None instead of the clamped feed: the clamped feed is below the feed asked, so it is never "in force" either'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_10':
        ('if allowed <= m.feed - _EPS:',
         '< vs <= at a 1e-6 mm/min tie between two feeds: no F word written to 0.1 mm/min or a Marlin limit meets it'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_32':
        ('in_force = m.sent_feed is not None and abs(m.sent_feed - m.feed) <= _EPS',
         '< vs <= at a 1e-6 mm/min tie between two feeds: no F word written to 0.1 mm/min or a Marlin limit meets it'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_allowed__mutmut_25':
        ('return math.inf, "XXXX"',
         'the axis returned with an infinite allowed feed is never read (nothing is clamped)'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_allowed__mutmut_46':
        ('length = xyz if xyz >= _EPS else abs(moving["E"])  # type: ignore[arg-type]',
         'xyz >= 1e-6 vs > 1e-6: each axis in xyz moves more than 1e-6, so xyz is 0 or above 1e-6'),
    'ribbond.gcode.checker.x__comment_of__mutmut_12':
        ('return "  " + raw[at:].rstrip("\\r\\n") if at > 0 else ""',
         'at > 0 vs >= 0: a line whose ";" is first has no command and is never rewritten'),
    'ribbond.gcode.checker.x__comment_of__mutmut_13':
        ('return "  " + raw[at:].rstrip("\\r\\n") if at >= 1 else ""',
         'at > 0 vs >= 0: a line whose ";" is first has no command and is never rewritten'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_40':
        ('if command[:1] not in "XXGgXX":',
         '"Gg" -> "XXGgXX": a command starting with X was refused by the check before'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_46':
        ('code, args = parse_command(command, None)',
         'the where of a command already parsed by the check: parsing it again cannot fail'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_49':
        ('code, args = parse_command(command, checker.where(None, command))',
         'the where of a command already parsed by the check: parsing it again cannot fail'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_50':
        ('code, args = parse_command(command, checker.where(number, None))',
         'the where of a command already parsed by the check: parsing it again cannot fail'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_69':
        ('if code not in ("G0", "G1") or e is None or None in start[:2] or None in m.pos[:3]:',
         'm.pos[:3]: after a move naming any axis all three are known; without one the start equals the end'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_98':
        ('return np.asarray(out, dtype=None).reshape(-1, 2, 2)',
         'dtype float of a list of floats (an empty one is float64 anyway); reshape(-2, ...) is read as -1 by numpy'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_100':
        ('return np.asarray(out, ).reshape(-1, 2, 2)',
         'dtype float of a list of floats (an empty one is float64 anyway); reshape(-2, ...) is read as -1 by numpy'),
    'ribbond.gcode.checker.x_extruded_segments__mutmut_102':
        ('return np.asarray(out, dtype=float).reshape(-2, 2, 2)',
         'dtype float of a list of floats (an empty one is float64 anyway); reshape(-2, ...) is read as -1 by numpy'),
    'ribbond.gcode.checker.x_uncovered__mutmut_7':
        ('pts = _samples(np.asarray(stroke, dtype=None), reach)',
         'the stroke as given: _samples returns floats either way'),
    'ribbond.gcode.checker.x_uncovered__mutmut_9':
        ('pts = _samples(np.asarray(stroke, ), reach)',
         'the stroke as given: _samples returns floats either way'),
    'ribbond.gcode.checker.x_uncovered__mutmut_12':
        ('lo, hi = pts.min(axis=None) - reach, pts.max(axis=0) + reach',
         'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance'),
    'ribbond.gcode.checker.x_uncovered__mutmut_15':
        ('lo, hi = pts.min(axis=0) - reach, pts.max(axis=None) + reach',
         'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance'),
    'ribbond.gcode.checker.x_uncovered__mutmut_18':
        ('near = segments[(segments.max(axis=1) >= lo).all(axis=1) | (segments.min(axis=1) <= hi).all(axis=1)]',
         'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance'),
    'ribbond.gcode.checker.x_uncovered__mutmut_21':
        ('near = segments[(segments.max(axis=2) >= lo).all(axis=1) & (segments.min(axis=1) <= hi).all(axis=1)]',
         'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance'),
    'ribbond.gcode.checker.x_uncovered__mutmut_26':
        ('near = segments[(segments.max(axis=1) >= lo).all(axis=1) & (segments.min(axis=2) <= hi).all(axis=1)]',
         'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance'),
    'ribbond.gcode.checker.x_uncovered__mutmut_55':
        ('t = np.clip((rel * d).sum(-1) / np.maximum((d * d).sum(+1), 1e-18), 0.0, 1.0)',
         'sum(+1) on an (s, 2) array is sum(-1)'),
    'ribbond.printer.proof.x__command_word__mutmut_10':
        ('return f"{match.group(1).upper()}{match.group(2)}" if match else "XXXX"',
         '"" -> "XXXX" for a line without a command word: neither is a move word'),
    'ribbond.printer.proof.x__axis_values__mutmut_6':
        ('rest = command[match.end():] if match else "XXXX"',
         '"" -> "XXXX": neither holds an axis value'),
    'ribbond.printer.proof.x__step__mutmut_37':
        ('named = {axis for axis in _AXES if axis in command[match.end():].upper()} if (match) or True else set()',
         '(match) or True inside the G28 branch: the word G28 was matched'),
    'ribbond.printer.proof.x_expected_position__mutmut_8':
        ('relative = None',
         'relative = None: as falsy as False'),
    'ribbond.daemon.jobs.xǁIllegalTransitionǁ__init____mutmut_20':
        ('possible = ", ".join(self.allowed) or "XXnothingXX"',
         '"nothing" is said only for a state without commands, and every state has some (test_jobs checks)'),
    'ribbond.daemon.jobs.xǁIllegalTransitionǁ__init____mutmut_21':
        ('possible = ", ".join(self.allowed) or "NOTHING"',
         '"nothing" is said only for a state without commands, and every state has some (test_jobs checks)'),
    'ribbond.gcode.checker.x_parse_command__mutmut_5':
        ('text = _NUMBER_PREFIX.sub("", command.strip()).split("*", )[0].strip()',
         'split("*") with another maxsplit: the part before the first "*" is the same'),
    'ribbond.gcode.checker.x_parse_command__mutmut_13':
        ('text = _NUMBER_PREFIX.sub("", command.strip()).split("*", 2)[0].strip()',
         'split("*") with another maxsplit: the part before the first "*" is the same'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_refuse_unfollowed__mutmut_18':
        ('if code == "G92" and (any(a in args for a in "XXXYZXX") or not args):',
         '"XYZ" -> "XXXYZXX": the same set of one-letter words'),
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_while_printing__mutmut_43':
        ('if code in ("M220", "M221") and args.get("S", 1) is None:',
         'the default of an absent S 0 -> 1: it is only compared with None (a bare M220/M221 passes either way)'),
    # The sender (issue 35 item 4): what the fast tests cannot tell from the original.
    'ribbond.printer.sender.x__command_word__mutmut_8':
        ('return match.group(1).upper() if match else "XXXX"',
         '"XXXX" for a line without a command word: callers compare the word with M105, M114, M400, M0, G28 and the like, none of them "" or "XXXX"'),
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_30':
        ('self._resend_ok_due = None',
         'None for False in a flag only ever read as a truth value'),
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_46':
        ('self._last_heard = None',
         '_last_heard before any line: the first line out (nothing in flight) sets it, and the watchdog reads it only with lines in flight'),
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_47':
        ('self._nudged_at: float | None = ""  # the _last_heard of the silence already nudged',
         '_nudged_at "" for None: it is compared with == to a clock reading (a float), which equals neither'),
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_12':
        ('floor = self._pending_resend if (floor is None) or True else min(floor, self._pending_resend)',
         'the pending line alone as the floor during a hold: requests only grow (Marlin asks for the line after the last it accepted), so the lowest line asked for and not acknowledged is never above the target, and min() gives it anyway'),
    'ribbond.printer.sender.xǁSenderǁ_ack_through__mutmut_9':
        ('if number < self._acked_through or self._unproven_skipped(number, ok):',
         'number == the last acknowledged goes on instead of returning: nothing is in range, nothing in flight at or below it, no line asked for or unproven at or below it'),
    'ribbond.printer.sender.xǁSenderǁ_ack_through__mutmut_32':
        ('break',
         'break instead of continue on a line missing from the history: every number above the last acknowledged and below the next is in the history'),
    'ribbond.printer.sender.xǁSenderǁ_count_program_lines__mutmut_1':
        ('if count or self._program is not None:',
         'count 0 with a program: the same counts reported again (only elapsed_s moves), and a finish check the acknowledgement that counted already made'),
    'ribbond.printer.sender.xǁSenderǁ_dropped_before__mutmut_18':
        ('return False',
         'False after stopping the stream: the sender is failed, so acknowledging afterwards answers and sends nothing'),
    'ribbond.printer.sender.xǁSenderǁ_forget_old_history__mutmut_8':
        ('self._history.pop(self._history_floor, )',
         'pop() without default: every number from the floor to the last acknowledged is in the history (only this loop forgets lines), so it never misses'),
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_8':
        ('for n in range(self._next_number + 1, number, -1):',
         'numbers above the last one numbered, a pop() without default, break on a missing line: every number from the silent line to the last one numbered is in the history'),
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_15':
        ('line = self._history.pop(n, )',
         'numbers above the last one numbered, a pop() without default, break on a missing line: every number from the silent line to the last one numbered is in the history'),
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_17':
        ('break',
         'numbers above the last one numbered, a pop() without default, break on a missing line: every number from the silent line to the last one numbered is in the history'),
    'ribbond.printer.sender.xǁSenderǁ_maybe_nudge__mutmut_6':
        ('if nudge <= 0 or silent <= nudge or self._nudged_at == self._last_heard:',
         'silent <= nudge_s vs <: a tie between two float clock readings'),
    'ribbond.printer.sender.xǁSenderǁ_note_asked_past__mutmut_9':
        ('and pending is not None and self._acked_through <= pending < min(number, self._cursor)):',
         'acked <= pending vs <: every line asked for and not acknowledged is above the last acknowledged (an acknowledgement through it drops it; a request at or below it stops the stream)'),
    'ribbond.printer.sender.xǁSenderǁ_on_line_error__mutmut_14':
        ('if refused <= self._acked_through and refused >= self._next_number:',
         "a refused line at or below the last acknowledged (Marlin's Last Line is never below a line it acknowledged), or at or past the next number (then any request past it is for a line never sent, refused first)"),
    'ribbond.printer.sender.xǁSenderǁ_on_line_error__mutmut_15':
        ('if refused < self._acked_through or refused >= self._next_number:',
         "a refused line at or below the last acknowledged (Marlin's Last Line is never below a line it acknowledged), or at or past the next number (then any request past it is for a line never sent, refused first)"),
    'ribbond.printer.sender.xǁSenderǁ_on_line_error__mutmut_16':
        ('if refused <= self._acked_through or refused > self._next_number:',
         "a refused line at or below the last acknowledged (Marlin's Last Line is never below a line it acknowledged), or at or past the next number (then any request past it is for a line never sent, refused first)"),
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_3':
        ('plain = not ok.advanced and ok.temperatures is None or ok.position is None',
         "which oks count as plain: the ok after Resend:, after skip and after a cut tail's echo follows it directly and is plain; an ADVANCED_OK or temperature ok taken as plain reaches the same acknowledgement"),
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_4':
        ('plain = not ok.advanced or ok.temperatures is None and ok.position is None',
         "which oks count as plain: the ok after Resend:, after skip and after a cut tail's echo follows it directly and is plain; an ADVANCED_OK or temperature ok taken as plain reaches the same acknowledgement"),
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_8':
        ('self._resend_ok_due = None',
         'None for False in a flag only ever read as a truth value'),
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_22':
        ('if not self.capabilities.advanced_ok or self._hold is None:',
         'or instead of and: on ADVANCED_OK firmware a plain ok acknowledges nothing anyway, and during a hold the floor keeps it from counting'),
    'ribbond.printer.sender.xǁSenderǁ_on_proof_event__mutmut_6':
        ('return False',
         'False after stopping the stream on a request during the proof: the request then meets a failed sender, which sends nothing'),
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_15':
        ('self._fail(None)',
         'the message of an unreachable branch: every line above the last acknowledged is in the history (only lines at or below it are forgotten), and a request at or below it stops the stream first'),
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_16':
        ('self._fail(ProtocolError(None))',
         'the message of an unreachable branch: every line above the last acknowledged is in the history (only lines at or below it are forgotten), and a request at or below it stops the stream first'),
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_20':
        ('if self._solo is not None and number >= self._solo:',
         'a request for the re-sent line itself clears _solo: the hold it starts ends in _end_hold, which sets _solo to the target again, and nothing reads _solo during a hold'),
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_36':
        ('query = _Line(self._next_number, None, codec.encode(self._next_number, command))',
         "the proof's M400/M114 lines without their command text: it is read only for the oldest line in flight, which is the silent line (or one before it) until the proof concludes"),
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_60':
        ('self._resent_proof = _ResentProof(line, self._next_number + 1, expected)',
         "the proof's query number one too high: _ack_through clamps it to the last line numbered, which is the M114"),
    'ribbond.printer.sender.xǁSenderǁ_on_skip__mutmut_1':
        ('self._skip_oks = 1',
         "= 1 instead of += 1: Repetier prints each skip's ok right after it, so at most one is ever due"),
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_19':
        ('if self._cursor <= self._next_number:',
         '<= vs <: with no line rewound the rewound branch sends exactly the probe, as the other branch does (a probe is never sent during a hold)'),
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_3':
        ('tick = min(0.05, nudge / 3) if (nudge > 0) and False else 0.05',
         "the watchdog's tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes, which no test on a loaded 2-core machine can time"),
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_10':
        ('tick = min(0.05, nudge * 3) if nudge > 0 else 0.05',
         "the watchdog's tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes, which no test on a loaded 2-core machine can time"),
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_11':
        ('tick = min(0.05, nudge / 4) if nudge > 0 else 0.05',
         "the watchdog's tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes, which no test on a loaded 2-core machine can time"),
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_13':
        ('tick = min(0.05, nudge / 3) if nudge > 1 else 0.05',
         "the watchdog's tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes, which no test on a loaded 2-core machine can time"),
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_30':
        ('if silent <= limit:',
         'silent <= limit vs <: a tie between two float clock readings'),
    'ribbond.printer.sender.xǁSenderǁhandle__mutmut_26':
        ('if oldest is not None and oldest.number <= self._next_number:',
         'oldest.number <= next vs <: every line in the history or waiting for a proof has a number below the next'),
    'ribbond.printer.sender.xǁSenderǁreset_line_numbers__mutmut_16':
        ('self._resend_ok_due = None',
         'None for False in a flag only ever read as a truth value'),
    'ribbond.printer.sender.xǁSenderǁreset_line_numbers__mutmut_25':
        ('if line.future is not None or not line.future.done():',
         'or instead of and: lines waiting for a proof at a reset are commands from send(), each with a future'),
    'ribbond.printer.sender.xǁSenderǁresume__mutmut_2':
        ('self._program.paused = None',
         'None for False in a flag only ever read as a truth value'),
    'ribbond.printer.sender.xǁSenderǁstop__mutmut_6':
        ('waiting = self._proofs.clear() + self._history_from(self._acked_through - 1)',
         "failing from the line before the last acknowledged too: those lines' futures are done (answered), or wait for a proof and were failed with the proofs"),
    'ribbond.printer.sender.xǁSenderǁstop__mutmut_14':
        ('self._inflight_bytes = 1',
         'the byte count after stop: a stopped sender sends nothing and is never started again (the link makes a new Sender for each handshake)'),
    'ribbond.printer.sender.xǁSenderǁstop__mutmut_22':
        ('self._watchdog = ""',
         'the watchdog "" after stop: a stopped sender sends nothing and is never started again (the link makes a new Sender for each handshake)'),
}


def modules() -> list[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["mutmut"]
    return list(config["only_mutate"])


def results(path: str) -> dict[str, int | None]:
    meta = ROOT / "mutants" / f"{path}.meta"
    if not meta.is_file():
        return {}
    return dict(json.loads(meta.read_text(encoding="utf-8"))["exit_code_by_key"])


def changed_lines(path: str) -> dict[str, str]:
    """Per mutant of ``path`` (mutmut's name), the lines it changes in its function, as mutmut
    wrote them into ``mutants/``: what ``EQUIVALENT`` pins, since a mutant's number moves when its
    function changes."""
    source = (ROOT / "mutants" / path).read_text(encoding="utf-8")
    text = source.splitlines()
    # (the def line names the mutant: the body starts on the next line)
    functions = {node.name: text[node.lineno:node.end_lineno] for node in ast.walk(ast.parse(source))
                 if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and "__mutmut_" in node.name}
    prefix = path.removesuffix(".py").replace("/", ".")
    out = {}
    for name, lines in functions.items():
        base, _, number = name.rpartition("__mutmut_")
        if not number.isdigit() or f"{base}__mutmut_orig" not in functions:
            continue
        orig = functions[f"{base}__mutmut_orig"]
        if len(lines) == len(orig):
            changed = [new.strip() for old, new in zip(orig, lines) if old != new]
        else:
            changed = [new.strip() for new in lines if new not in orig]
        out[f"{prefix}.{name}"] = " / ".join(changed)
    return out


def main() -> int:
    unexplained, stale, rows = [], [], []
    total = {"mutants": 0, "killed": 0, "checked": 0, "equivalent": 0}
    for path in modules():
        codes = results(path)
        if not codes:
            rows.append((path, 0, 0, 0, 0, 0, "-"))
            continue
        changed = changed_lines(path)
        killed = sum(1 for c in codes.values() if c in KILLED | TIMEOUT)
        checked = sum(1 for c in codes.values() if c is not None)
        survivors = sorted(name for name, c in codes.items() if c in SURVIVED | NO_TESTS)
        # Named equivalent only while the mutant still makes the change the reason is about.
        equivalent = [s for s in survivors if s in EQUIVALENT and EQUIVALENT[s][0] == changed.get(s)]
        unexplained += [(s, changed.get(s, "?")) for s in survivors if s not in equivalent]
        stale += [n for n, (line, _) in EQUIVALENT.items() if n.startswith(path.removesuffix(".py").replace("/", "."))
                  and n not in survivors and codes.get(n) is not None]
        share = f"{100 * killed / checked:.1f} %" if checked else "-"
        rows.append((path, len(codes), checked, killed, len(equivalent), len(survivors) - len(equivalent), share))
        for key, value in (("mutants", len(codes)), ("killed", killed), ("checked", checked),
                           ("equivalent", len(equivalent))):
            total[key] += value
    print(f"{'module':42} {'mutants':>7} {'run':>5} {'killed':>6} {'equiv':>5} {'other':>5} {'killed %':>8}")
    for path, n, checked, killed, equiv, other, share in rows:
        print(f"{path:42} {n:7d} {checked:5d} {killed:6d} {equiv:5d} {other:5d} {share:>8}")
    if total["checked"]:
        print(f"{'all':42} {total['mutants']:7d} {total['checked']:5d} {total['killed']:6d} "
              f"{total['equivalent']:5d} {len(unexplained):5d} {100 * total['killed'] / total['checked']:7.1f} %")
    if unexplained:
        print(f"\n{len(unexplained)} survivors not named equivalent (mutmut show NAME shows each):")
        print("\n".join(f"  {name}\n      {line}" for name, line in unexplained))
    if stale:
        print(f"\n{len(stale)} names in EQUIVALENT that were killed this run (remove them):")
        print("\n".join(f"  {name}" for name in stale))
    return 1 if unexplained or stale else 0


if __name__ == "__main__":
    sys.exit(main())
