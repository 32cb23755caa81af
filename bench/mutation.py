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
