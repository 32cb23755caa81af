"""Benchmark of panels (issue 26): surfaces one sheet cannot make, cut, designed, predicted and sewn.

Two targets from ``ribbond.design.surfaces``:
- a hemisphere of 100 mm (radius 50 mm, 5,400 faces): one sheet breaks the stretch bounds on most
  of its faces; goals: every panel within the bounds (≤ 1 % of faces out) and the frame, the
  assembled prediction's mean deviation ≤ 2 % of the diagonal (one sheet's is shown beside it), the
  seams' deployed lengths within 1 % of each other and of the target's;
- a saddle 300 mm across (z = (x²/300 − y²/600)/2 mm), wider than the 180 mm frame: panels that fit,
  each within the bounds, the assembled prediction reported.

Speed: cutting and designing N panels (``design_project``) against N single designs of the same
panels (``design_mesh`` on each panel's mesh, as a person would run them), both with the prediction;
goal ≤ 1.5×.

    python bench/panels.py [--only hemisphere|saddle]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ribbond.design import surfaces  # noqa: E402
from ribbond.design.errors import DesignError  # noqa: E402
from ribbond.design.intake import load_target  # noqa: E402
from ribbond.mesh.files import write_obj  # noqa: E402
from ribbond.panels.cut import panel_submesh  # noqa: E402
from ribbond.design.params import DesignParameters, SizeSpec, SolverSettings  # noqa: E402
from ribbond.pipeline.compile import design_mesh  # noqa: E402
from ribbond.panels.project import MAX_BAD_PCT, design_project, panel_margin, write_project  # noqa: E402

GOAL_DEVIATION_PCT = 2.0
GOAL_SEAM_PCT = 1.0
GOAL_SPEED = 1.5


def _targets() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {"hemisphere": surfaces.sphere_cap(50.0, 90.0, rings=30),
            "saddle": surfaces.saddle(300.0, 1.0 / 300.0, 1.0 / 600.0, rings=40)}


def _single_designs(result, workdir: Path) -> float:
    """Seconds for designing each panel's mesh on its own (with the prediction), one after another."""
    total = 0.0
    for k, panel in enumerate(result.panels, start=1):
        Vp, Fp, _, _ = panel_submesh(result.V, result.F, result.cut.labels, k - 1)
        path = workdir / f"panel-{k}.obj"
        write_obj(path, Vp, Fp)
        diag = float(np.linalg.norm(Vp.max(axis=0) - Vp.min(axis=0)))
        t = time.perf_counter()
        margin = panel_margin(SolverSettings(), result.seam_allowance, DesignParameters().prestretch)
        design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=diag)),
                    SolverSettings(refine_below_faces=0, layout_margin=margin))
        total += time.perf_counter() - t
    return total


def _one_sheet(path: Path) -> str:
    """The one-sheet design of the whole target as the baseline: at its size, or, when one sheet cannot
    hold it at that size, at the largest size that fits the frame (the deviation is in % of the
    diagonal, so the two compare)."""
    V = load_target(path, max_faces=400_000).V
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    try:
        r, how = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=diag))), "at its size"
    except DesignError:
        r = design_mesh(path, DesignParameters())
        how = f"too large for one sheet at its size; at {r.design.parameters.size.bbox_diagonal:.0f} mm"
    rep = r.design.report
    return (f"one sheet ({how}): {max(rep.sigma1_bad_pct, rep.sigma2_bad_pct):.1f} % of faces outside the "
            f"bounds, predicted mean deviation {rep.deployed.deviation_pct.mean:.2f} % of the diagonal")


def run(name: str, V: np.ndarray, F: np.ndarray, out: Path) -> None:
    path = out / f"{name}.obj"
    write_obj(path, V, F)
    print(f"\n== {name}: {len(F)} faces, bounding-box diagonal {np.linalg.norm(V.max(0) - V.min(0)):.0f} mm")
    print("  " + _one_sheet(path), flush=True)
    t = time.perf_counter()
    result = design_project(path, DesignParameters())
    t_project = time.perf_counter() - t
    write_project(result, out / f"{name}-project")
    print(f"  panels: {result.cut.count} (tried: " + ", ".join(
        f"{d['panels']} {d['cut']} {d['worst_bad_pct']:.1f} %{'' if d['fit'] else ' too large'}"
        for d in result.cut.tried) + ")")
    for k, (panel, check) in enumerate(zip(result.panels, result.cut.checks), start=1):
        rep = panel.result.design.report
        bad = max(rep.sigma1_bad_pct, rep.sigma2_bad_pct)
        w, h = panel.result.flat_uv.max(0) - panel.result.flat_uv.min(0)
        print(f"  panel {k}: {bad:.2f} % of faces out of bounds ({'ok' if bad <= MAX_BAD_PCT else 'NOT met'}), "
              f"flat {w:.0f} × {h:.0f} mm, predicted mean deviation {rep.deployed.deviation_pct.mean:.2f} %")
    worst = max(s.length_mismatch_pct for s in result.seams)
    print(f"  seams: {len(result.seams)}; worst deployed-length mismatch {worst:.2f} % "
          f"(goal ≤ {GOAL_SEAM_PCT:g} %: {'met' if worst <= GOAL_SEAM_PCT else 'NOT met'})")
    for s in result.seams:
        print(f"    {s.label} panels {s.panels[0] + 1}–{s.panels[1] + 1}: target {s.target_length:.1f} mm, deployed "
              f"{s.deployed_length[0]:.1f} / {s.deployed_length[1]:.1f} mm ({s.length_mismatch_pct:.2f} %)")
    a = result.assembly
    d = a.deviation_pct
    print(f"  assembled prediction: mean {d['mean']:.2f} %, p99 {d['p99']:.2f} %, max {d['max']:.2f} % of the "
          f"diagonal (goal mean ≤ {GOAL_DEVIATION_PCT:g} %: {'met' if d['mean'] <= GOAL_DEVIATION_PCT else 'NOT met'}); "
          f"seams closed to {a.seam_gap_mm['max']:.4f} mm, {a.iterations} Newton iterations")
    with tempfile.TemporaryDirectory() as tmp:
        t_single = _single_designs(result, Path(tmp))
    ratio = t_project / t_single
    without = (t_project - result.timings.get("assemble", 0.0)) / t_single
    print(f"  time: project {t_project:.1f} s ({', '.join(f'{k} {v:.1f} s' for k, v in result.timings.items())}); "
          f"{result.cut.count} single designs {t_single:.1f} s; ratio {ratio:.2f} "
          f"(goal ≤ {GOAL_SPEED:g}: {'met' if ratio <= GOAL_SPEED else 'NOT met'}); "
          f"without the sewn prediction, which single designs do not make: {without:.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("hemisphere", "saddle"))
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench-panels")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name, (V, F) in _targets().items():
        if args.only in (None, name):
            run(name, V, F, args.out)


if __name__ == "__main__":
    main()
