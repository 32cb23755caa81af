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
    "ribbond.gcode.checker.x__feed_text__mutmut_12":
        'rstrip("0") -> rstrip("XX0XX"): the set of characters stripped gains "X", which a number never holds',
    "ribbond.gcode.checker.x__feed_text__mutmut_13":
        'rstrip(".") -> rstrip("XX.XX"): likewise',
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
