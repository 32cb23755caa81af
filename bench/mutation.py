"""The figures of ``make mutate`` (issue 35): per safety module, the mutants mutmut made, the share the
fast tests killed, and every survivor, the equivalent ones (``EQUIVALENT``: no test can tell them from
the original; why is given) apart from the rest. Reads mutmut's results under ``mutants/``; run from the
repository's root after ``mutmut run``. Exits 1 when a survivor is not named equivalent.

    python bench/mutation.py            # the table and the survivors
"""

from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: mutmut's exit codes: 1 and 3 a test failed (killed); a timeout (the mutant hangs the tests) is
#: counted as killed too (pytest-timeout would fail it); 0 survived; 5 and 33 no test covers it.
KILLED, TIMEOUT, SURVIVED, NO_TESTS = {1, 3}, {24, -24, 36, 152, 255}, {0}, {5, 33}

#: Survivors no test can kill: the mutant behaves as the original on every input the code can get.
EQUIVALENT: dict[str, str] = {
    'ribbond.gcode.checker.x__feed_text__mutmut_12':
        'rstrip("0")/rstrip(".") gain "X" in the set stripped: a number never ends in X',
    'ribbond.gcode.checker.x__feed_text__mutmut_13':
        'rstrip("0")/rstrip(".") gain "X" in the set stripped: a number never ends in X',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_43':
        'likewise: rstrip of a formatted number gains "X"',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_44':
        'likewise: rstrip of a formatted number gains "X"',
    'ribbond.gcode.checker.xǁGcodeCheckerǁcheck__mutmut_11':
        'split("*") with another maxsplit: the part before the first "*" is the same',
    'ribbond.gcode.checker.xǁGcodeCheckerǁcheck__mutmut_20':
        'split("*") with another maxsplit: the part before the first "*" is the same',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_19':
        'the checksum cut before GcodeChecker.command, which cuts it again the same way',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_20':
        'the checksum cut before GcodeChecker.command, which cuts it again the same way',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_27':
        'the checksum cut before GcodeChecker.command, which cuts it again the same way',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_28':
        'the checksum cut before GcodeChecker.command, which cuts it again the same way',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_move__mutmut_13':
        '"XYZEF"/"XYZ" -> "XXXYZEFXX"/"XXXYZXX": the same set of one-letter words',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_move__mutmut_31':
        '"XYZEF"/"XYZ" -> "XXXYZEFXX"/"XXXYZXX": the same set of one-letter words',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_end__mutmut_22':
        '"XYZ" -> "XXXYZXX": the same set of one-letter words',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_21':
        'sent_feed None instead of the clamped feed: the clamped feed is below the feed asked, so it is never "in force" either',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_10':
        '< vs <= at a 1e-6 mm/min tie between two feeds: no F word written to 0.1 mm/min or a Marlin limit meets it',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_clamped__mutmut_32':
        '< vs <= at a 1e-6 mm/min tie between two feeds: no F word written to 0.1 mm/min or a Marlin limit meets it',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_allowed__mutmut_25':
        'the axis returned with an infinite allowed feed is never read (nothing is clamped)',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_allowed__mutmut_46':
        'xyz >= 1e-6 vs > 1e-6: each axis in xyz moves more than 1e-6, so xyz is 0 or above 1e-6',
    'ribbond.gcode.checker.x__comment_of__mutmut_12':
        'at > 0 vs >= 0: a line whose ";" is first has no command and is never rewritten',
    'ribbond.gcode.checker.x__comment_of__mutmut_13':
        'at > 0 vs >= 0: a line whose ";" is first has no command and is never rewritten',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_40':
        '"Gg" -> "XXGgXX": a command starting with X was refused by the check before',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_46':
        'the where of a command already parsed by the check: parsing it again cannot fail',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_49':
        'the where of a command already parsed by the check: parsing it again cannot fail',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_50':
        'the where of a command already parsed by the check: parsing it again cannot fail',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_69':
        'm.pos[:3]: after a move naming any axis all three are known; without one the start equals the end',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_98':
        'dtype float of a list of floats (an empty one is float64 anyway); reshape(-2, ...) is read as -1 by numpy',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_100':
        'dtype float of a list of floats (an empty one is float64 anyway); reshape(-2, ...) is read as -1 by numpy',
    'ribbond.gcode.checker.x_extruded_segments__mutmut_102':
        'dtype float of a list of floats (an empty one is float64 anyway); reshape(-2, ...) is read as -1 by numpy',
    'ribbond.gcode.checker.x_uncovered__mutmut_7':
        'the stroke as given: _samples returns floats either way',
    'ribbond.gcode.checker.x_uncovered__mutmut_9':
        'the stroke as given: _samples returns floats either way',
    'ribbond.gcode.checker.x_uncovered__mutmut_12':
        'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance',
    'ribbond.gcode.checker.x_uncovered__mutmut_15':
        'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance',
    'ribbond.gcode.checker.x_uncovered__mutmut_18':
        'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance',
    'ribbond.gcode.checker.x_uncovered__mutmut_21':
        'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance',
    'ribbond.gcode.checker.x_uncovered__mutmut_26':
        'the prefilter of segments made looser: it only skips segments farther than reach; keeping more changes no distance',
    'ribbond.gcode.checker.x_uncovered__mutmut_55':
        'sum(+1) on an (s, 2) array is sum(-1)',
    'ribbond.printer.proof.x__command_word__mutmut_10':
        '"" -> "XXXX" for a line without a command word: neither is a move word',
    'ribbond.printer.proof.x__axis_values__mutmut_6':
        '"" -> "XXXX": neither holds an axis value',
    'ribbond.printer.proof.x__step__mutmut_37':
        '(match) or True inside the G28 branch: the word G28 was matched',
    'ribbond.printer.proof.x_expected_position__mutmut_8':
        'relative = None: as falsy as False',
    'ribbond.daemon.jobs.xǁIllegalTransitionǁ__init____mutmut_20':
        '"nothing" is said only for a state without commands, and every state has some (test_jobs checks)',
    'ribbond.daemon.jobs.xǁIllegalTransitionǁ__init____mutmut_21':
        '"nothing" is said only for a state without commands, and every state has some (test_jobs checks)',
    'ribbond.gcode.checker.x_parse_command__mutmut_5':
        'split("*") with another maxsplit: the part before the first "*" is the same',
    'ribbond.gcode.checker.x_parse_command__mutmut_13':
        'split("*") with another maxsplit: the part before the first "*" is the same',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_refuse_unfollowed__mutmut_18':
        '"XYZ" -> "XXXYZXX": the same set of one-letter words',
    'ribbond.gcode.checker.xǁGcodeCheckerǁ_refuse_unfollowed__mutmut_48':
        'M220 without S read as S1 instead of S0: both are under 100 %',
    # The sender (issue 35 item 4): what the fast tests cannot tell from the original.
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_21':
        'a log line (debug): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_22':
        'a log line (debug): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_23':
        'a log line (debug): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_24':
        'a log line (debug): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_25':
        'a log line (debug): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_26':
        'a log line (debug): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_9':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_10':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_11':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_12':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_13':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_14':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_15':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_16':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_fail__mutmut_2':
        'a log line (error): the reason itself goes to every waiting future unchanged',
    'ribbond.printer.sender.xǁSenderǁ_fail__mutmut_3':
        'a log line (error): the reason itself goes to every waiting future unchanged',
    'ribbond.printer.sender.xǁSenderǁ_fail__mutmut_4':
        'a log line (error): the reason itself goes to every waiting future unchanged',
    'ribbond.printer.sender.xǁSenderǁ_fail__mutmut_5':
        'a log line (error): the reason itself goes to every waiting future unchanged',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_59':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_60':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_61':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_62':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_63':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_64':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_65':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_66':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_67':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_68':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_31':
        'a log line (warning): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_32':
        'a log line (warning): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_33':
        'a log line (warning): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_34':
        'a log line (warning): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_19':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_20':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_21':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_22':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_23':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_24':
        'a log line (info): its text and arguments change nothing the sender does',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_16':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_18':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_22':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_23':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_26':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_37':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_39':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_43':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_44':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_follow_up__mutmut_45':
        'the number and bytes of a query not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_next_fresh__mutmut_13':
        'the number and bytes of a program line not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_next_fresh__mutmut_15':
        'the number and bytes of a program line not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_next_fresh__mutmut_21':
        'the number and bytes of a program line not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_next_fresh__mutmut_22':
        'the number and bytes of a program line not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_next_fresh__mutmut_23':
        'the number and bytes of a program line not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁsend__mutmut_6':
        'the number and bytes of a command not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁsend__mutmut_8':
        'the number and bytes of a command not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁsend__mutmut_14':
        'the number and bytes of a command not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁsend__mutmut_15':
        'the number and bytes of a command not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁsend__mutmut_16':
        'the number and bytes of a command not yet numbered: _pump gives it its number and encodes it before it is sent or read',
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_19':
        'the number, bytes and offset of a line that gave its number back: a program line is made afresh from its index, a command gets them again in _pump',
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_20':
        'the number, bytes and offset of a line that gave its number back: a program line is made afresh from its index, a command gets them again in _pump',
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_21':
        'the number, bytes and offset of a line that gave its number back: a program line is made afresh from its index, a command gets them again in _pump',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_28':
        'None for False in a flag only ever read as a truth value',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_33':
        'None for False in a flag only ever read as a truth value',
    'ribbond.printer.sender.xǁSenderǁreset_line_numbers__mutmut_16':
        'None for False in a flag only ever read as a truth value',
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_8':
        'None for False in a flag only ever read as a truth value',
    'ribbond.printer.sender.xǁSenderǁstream__mutmut_19':
        'None for False in a flag only ever read as a truth value',
    'ribbond.printer.sender.xǁSenderǁresume__mutmut_1':
        'None for False in a flag only ever read as a truth value',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_29':
        '_paused starting True: it is read only for a program, and stream() sets it False before the first line',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_31':
        'the resend target and stale counts before any hold: each hold sets them before they are read',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_35':
        'the resend target and stale counts before any hold: each hold sets them before they are read',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_36':
        'the resend target and stale counts before any hold: each hold sets them before they are read',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_37':
        'the resend target and stale counts before any hold: each hold sets them before they are read',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_38':
        'the resend target and stale counts before any hold: each hold sets them before they are read',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_53':
        '_last_heard before any line: the first line sent (nothing in flight) sets it, and the watchdog reads it only with lines in flight',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_54':
        '_nudged_at is compared with == to a time.monotonic() reading, which is none of -1, +1 or -2',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_55':
        '_nudged_at is compared with == to a time.monotonic() reading, which is none of -1, +1 or -2',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_56':
        '_nudged_at is compared with == to a time.monotonic() reading, which is none of -1, +1 or -2',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_2':
        'the history kept one line longer: memory only; a request for a line at or below the last acknowledged stops the stream ("already acknowledged") before the history is read',
    'ribbond.printer.sender.xǁSenderǁ__init____mutmut_15':
        'the history kept one line longer: memory only; a request for a line at or below the last acknowledged stops the stream ("already acknowledged") before the history is read',
    'ribbond.printer.sender.xǁSenderǁreset_line_numbers__mutmut_8':
        'the history kept one line longer: memory only; a request for a line at or below the last acknowledged stops the stream before the history is read',
    'ribbond.printer.sender.xǁSenderǁ_forget_old_history__mutmut_3':
        'acknowledged lines forgotten later, or not at all: memory only; every number below the next one is in the history, so pop() never misses; nothing reads an acknowledged line',
    'ribbond.printer.sender.xǁSenderǁ_forget_old_history__mutmut_6':
        'acknowledged lines forgotten later, or not at all: memory only; every number below the next one is in the history, so pop() never misses; nothing reads an acknowledged line',
    'ribbond.printer.sender.xǁSenderǁ_forget_old_history__mutmut_8':
        'acknowledged lines forgotten later, or not at all: memory only; every number below the next one is in the history, so pop() never misses; nothing reads an acknowledged line',
    'ribbond.printer.sender.xǁSenderǁ_forget_old_history__mutmut_11':
        'acknowledged lines forgotten later, or not at all: memory only; every number below the next one is in the history, so pop() never misses; nothing reads an acknowledged line',
    'ribbond.printer.sender.x__command_word__mutmut_8':
        '"XXXX" for a line without a command word: no caller compares a word with it',
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_6':
        'the floor taken from the resend target outside a hold too: outside a hold the target is None, as the floor was',
    'ribbond.printer.sender.xǁSenderǁ_ack_oldest__mutmut_12':
        'the pending request alone as the floor: while holding, the pending line is the lowest asked for, never above the target, so min() gives it anyway',
    'ribbond.printer.sender.xǁSenderǁ_ack_through__mutmut_9':
        'number == the last acknowledged goes on instead of returning: nothing is in range, nothing in flight at or below it, no unproven line at or below it',
    'ribbond.printer.sender.xǁSenderǁ_ack_through__mutmut_32':
        'break instead of continue on a line missing from the history: every number above the last acknowledged and below the next is in the history',
    'ribbond.printer.sender.xǁSenderǁ_ack_through__mutmut_58':
        "the pending request cleared one acknowledgement later: it differs only for an unnumbered ADVANCED_OK ok right after the line asked for is acknowledged; Marlin prints those only for cut tails, which come during the episode, before that line's ok",
    'ribbond.printer.sender.xǁSenderǁ_conclude_proof__mutmut_18':
        "the proof's ok as None: it reaches only program lines (no future to answer) and _unproven_skipped, which needs ADVANCED_OK, where no proof is made",
    'ribbond.printer.sender.xǁSenderǁ_count_program_lines__mutmut_1':
        'count 0 with a program: the same progress told again, and the finish check already made on the acknowledgement that counted',
    'ribbond.printer.sender.xǁSenderǁ_dropped_before__mutmut_18':
        'False after stopping the stream: the sender is failed, so acknowledging afterwards answers and sends nothing',
    'ribbond.printer.sender.xǁSenderǁ_end_hold__mutmut_3':
        'the target left "" after a hold: every hold sets it before it is read, and _on_skip reads it only during a hold',
    'ribbond.printer.sender.xǁSenderǁ_end_hold__mutmut_4':
        'and instead of or: a hold always has a target, and after a failure _pump sends nothing',
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_8':
        'numbers above the last one numbered, a pop() without default, break on a missing line: every number from the silent line to the last one numbered is in the history',
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_15':
        'numbers above the last one numbered, a pop() without default, break on a missing line: every number from the silent line to the last one numbered is in the history',
    'ribbond.printer.sender.xǁSenderǁ_give_back_numbers_after__mutmut_17':
        'numbers above the last one numbered, a pop() without default, break on a missing line: every number from the silent line to the last one numbered is in the history',
    'ribbond.printer.sender.xǁSenderǁ_maybe_nudge__mutmut_6':
        'silent <= nudge_s vs <: a tie between two float clock readings',
    'ribbond.printer.sender.xǁSenderǁ_note_asked_past__mutmut_9':
        'acked <= pending vs <: a pending request is cleared once its line is acknowledged, so it is always above the last acknowledged',
    'ribbond.printer.sender.xǁSenderǁ_on_line_error__mutmut_14':
        "a refused line at or below the last acknowledged (Marlin's Last Line is never below a line it acknowledged), or at or past the next number (then any request past it is for a line never sent, refused first)",
    'ribbond.printer.sender.xǁSenderǁ_on_line_error__mutmut_15':
        "a refused line at or below the last acknowledged (Marlin's Last Line is never below a line it acknowledged), or at or past the next number (then any request past it is for a line never sent, refused first)",
    'ribbond.printer.sender.xǁSenderǁ_on_line_error__mutmut_16':
        "a refused line at or below the last acknowledged (Marlin's Last Line is never below a line it acknowledged), or at or past the next number (then any request past it is for a line never sent, refused first)",
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_3':
        "which oks count as plain: the ok after Resend:, after skip and after a cut tail's echo follows it directly and is plain; an ADVANCED_OK or temperature ok taken as plain reaches the same acknowledgement",
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_4':
        "which oks count as plain: the ok after Resend:, after skip and after a cut tail's echo follows it directly and is plain; an ADVANCED_OK or temperature ok taken as plain reaches the same acknowledgement",
    'ribbond.printer.sender.xǁSenderǁ_on_ok__mutmut_22':
        'or instead of and: on ADVANCED_OK firmware a plain ok acknowledges nothing anyway, and during a hold the floor keeps it from counting',
    'ribbond.printer.sender.xǁSenderǁ_on_proof_event__mutmut_6':
        'False after stopping the stream on a request during the proof: the request then meets a failed sender, which sends nothing',
    'ribbond.printer.sender.xǁSenderǁ_on_proof_event__mutmut_12':
        'the position report not passed on: it would only be recorded among the events of a program line, which nothing reads (only ADVANCED-less processed-ok firmware proves, where runs are not tracked)',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_15':
        'the message of an unreachable branch: every line above the last acknowledged is in the history (only lines at or below it are forgotten), and a request at or below it stops the stream first',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_16':
        'the message of an unreachable branch: every line above the last acknowledged is in the history (only lines at or below it are forgotten), and a request at or below it stops the stream first',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_20':
        'a request for the re-sent line itself clears _solo: the hold it starts ends in _end_hold, which sets _solo to the target again',
    'ribbond.printer.sender.xǁSenderǁ_on_resend__mutmut_40':
        'number <= pending vs <: on a tie the same number is stored',
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_43':
        "the proof's M400/M114 lines without their command text: it is read only for the oldest line in flight, which is the silent line until the proof concludes",
    'ribbond.printer.sender.xǁSenderǁ_on_resent_silence__mutmut_67':
        "the proof's query number one too high: _ack_through clamps it to the last line numbered, which is the M114",
    'ribbond.printer.sender.xǁSenderǁ_on_skip__mutmut_1':
        "= 1 instead of += 1: Repetier prints each skip's ok right after it, so at most one is ever due",
    'ribbond.printer.sender.xǁSenderǁ_probe__mutmut_25':
        '<= vs <: with no line rewound the rewound branch sends exactly the probe, as the other branch does',
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_3':
        'the tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes; no test on a loaded 2-core machine can time 10 ms against 50 ms',
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_10':
        'the tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes; no test on a loaded 2-core machine can time 10 ms against 50 ms',
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_11':
        'the tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes; no test on a loaded 2-core machine can time 10 ms against 50 ms',
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_13':
        'the tick for the 30 ms nudge 50 or 7.5 ms instead of 10 ms: only how soon after the 30 ms the nudge goes; no test on a loaded 2-core machine can time 10 ms against 50 ms',
    'ribbond.printer.sender.xǁSenderǁ_watch__mutmut_30':
        'silent <= limit vs <: a tie between two float clock readings',
    'ribbond.printer.sender.xǁSenderǁhandle__mutmut_26':
        'oldest.number <= next vs <: every line in the history or waiting for a proof has a number below the next',
    'ribbond.printer.sender.xǁSenderǁreset_line_numbers__mutmut_25':
        'or instead of and: lines waiting for a proof at a reset are commands from send(), each with a future',
    'ribbond.printer.sender.xǁSenderǁstop__mutmut_7':
        'failing from the last acknowledged line too: its future is done already (answered, or failed with the proofs)',
    'ribbond.printer.sender.xǁSenderǁstop__mutmut_15':
        'the byte count or the watchdog after stop: a stopped sender sends nothing and never starts again',
    'ribbond.printer.sender.xǁSenderǁstop__mutmut_23':
        'the byte count or the watchdog after stop: a stopped sender sends nothing and never starts again',
}


def modules() -> list[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["mutmut"]
    return list(config["only_mutate"])


def results(path: str) -> dict[str, int | None]:
    meta = ROOT / "mutants" / f"{path}.meta"
    if not meta.is_file():
        return {}
    return dict(json.loads(meta.read_text(encoding="utf-8"))["exit_code_by_key"])


def main() -> int:
    unexplained, rows = [], []
    total = {"mutants": 0, "killed": 0, "checked": 0}
    for path in modules():
        codes = results(path)
        killed = sum(1 for c in codes.values() if c in KILLED | TIMEOUT)
        checked = sum(1 for c in codes.values() if c is not None)
        survivors = sorted(name for name, c in codes.items() if c in SURVIVED | NO_TESTS)
        equivalent = [s for s in survivors if s in EQUIVALENT]
        unexplained += [s for s in survivors if s not in EQUIVALENT]
        share = f"{100 * killed / checked:.1f} %" if checked else "-"
        rows.append((path, len(codes), checked, killed, len(equivalent), len(survivors) - len(equivalent), share))
        total["mutants"] += len(codes)
        total["killed"] += killed
        total["checked"] += checked
    print(f"{'module':42} {'mutants':>7} {'run':>5} {'killed':>6} {'equiv':>5} {'other':>5} {'killed %':>8}")
    for path, n, checked, killed, equiv, other, share in rows:
        print(f"{path:42} {n:7d} {checked:5d} {killed:6d} {equiv:5d} {other:5d} {share:>8}")
    if total["checked"]:
        print(f"{'all':42} {total['mutants']:7d} {total['checked']:5d} {total['killed']:6d} "
              f"{'':5} {'':5} {100 * total['killed'] / total['checked']:7.1f} %")
    if unexplained:
        print(f"\n{len(unexplained)} survivors (mutmut show NAME shows each):")
        print("\n".join(f"  {name}" for name in unexplained))
    return 1 if unexplained else 0


if __name__ == "__main__":
    sys.exit(main())
