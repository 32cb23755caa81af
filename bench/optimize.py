"""Benchmark of the layout optimized against the prediction (ribbond.deploy.optimize, issue 34).

For each surface (a cylinder patch 100 mm, the torus patch of Fig. 2 120 mm, a symmetric saddle
110 mm, a skew saddle (κx = 1/40, κy = 1/100 /mm) 110 mm, a shallow spherical cap (radius 60 mm,
half-angle 30°) 100 mm; sizes are bounding-box diagonals, ~10k faces each) it designs the forward
layout as ``ribbonctl design --no-optimize`` does (``design_mesh(predict=False)``), then runs the
stage optimize as the pipeline does: predicts it (every release), optimizes its thicknesses
(``optimize_layout``, what is left of the default budget), predicts the optimized layout again from
the flat sheet (every release), says whether the stage keeps it (``optimization_kept``:
its prediction better than the forward one's), and prints, each against the issue's goal:

- the predicted mean deviation, forward → optimized (≤ 1.0 %; ≤ 0.6 × the forward's where that is above 1 %);
- ∫K predicted / target, forward → optimized (within 10 %);
- the optimization's time (≤ 60 s at 10k faces), iterations, evaluations, why it stopped.

    python bench/optimize.py [--surfaces cylinder saddle ...]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SURFACES = ("cylinder", "torus_patch", "saddle", "skew_saddle", "shallow_cap")
GOAL_MEAN_PCT = 1.0
GOAL_RATIO = 0.6
GOAL_K = 0.10
GOAL_S = 60.0


def _mesh(name: str):
    from ribbond.design import surfaces
    if name == "cylinder":
        return (*surfaces.cylinder_patch(n_around=100, n_along=50), 100.0)
    if name == "torus_patch":
        return (*surfaces.torus_patch(nu=100, nv=50), 120.0)
    if name == "saddle":
        return (*surfaces.saddle(size=80.0, kappa_x=1 / 40.0, kappa_y=1 / 40.0, rings=40), 110.0)
    if name == "skew_saddle":
        return (*surfaces.saddle(size=80.0, kappa_x=1 / 40.0, kappa_y=1 / 100.0, rings=40), 110.0)
    if name == "shallow_cap":
        return (*surfaces.sphere_cap(radius=60.0, half_angle_deg=30.0, rings=40), 100.0)
    raise ValueError(f"unknown surface {name!r}")


def run(name: str) -> dict:
    from ribbond.deploy.optimize import optimize_layout
    from ribbond.deploy.predict import predict_deployed
    from ribbond.mesh.files import write_obj
    from ribbond.design.params import DesignParameters, SizeSpec, SolverSettings
    from ribbond.pipeline.compile import design_mesh
    from ribbond.design.thickness import load_curvature_table
    V, F, size = _mesh(name)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{name}.obj"
        write_obj(path, V, F)
        res = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=size)), predict=False)
    p = res.design.parameters
    kw = dict(prestretch=p.prestretch, ribbon_width=p.ribbon_width, table=load_curvature_table(p.curvature_table))
    uv, V, F, rib = res.flat_uv, res.V, res.F, res.design.ribbons
    t0 = time.perf_counter()                                                    # the stage optimize:
    forward = predict_deployed(uv, V, F, rib, **kw)                              # the forward layout, every release
    budget = max(SolverSettings().optimize_budget_s - (time.perf_counter() - t0), 1.0)     # as the stage
    opt = optimize_layout(uv, V, F, rib, forward, budget_s=budget, **kw)
    optimized = predict_deployed(uv, V, F, opt.ribbons, **kw)                    # from the flat sheet, every release
    stage_s = time.perf_counter() - t0
    from ribbond.pipeline.compile import optimization_kept
    kept, why = optimization_kept(forward, optimized)
    return {"kept": kept, "why": why, "surface": name, "faces": len(F), "ribbons": len(rib), "forward": forward, "optimized": optimized,
            "opt": opt, "stage_s": stage_s}


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def report(r: dict) -> None:
    f, o, opt = r["forward"], r["optimized"], r["opt"]
    fm, om = f.deviation_pct["mean"], o.deviation_pct["mean"]
    fa, oa = f.agreement, o.agreement
    kt = fa.curvature_target
    fk, ok = fa.curvature_predicted / kt, oa.curvature_predicted / kt
    goal = om <= GOAL_MEAN_PCT and (fm <= GOAL_MEAN_PCT or om <= GOAL_RATIO * fm)
    print(f"\n{r['surface']} ({r['faces']} faces, {r['ribbons']} ribbons)")
    print(f"  mean deviation {fm:.2f} → {om:.2f} % (p99 {f.deviation_pct['p99']:.2f} → {o.deviation_pct['p99']:.2f} %;"
          f" goal ≤ {GOAL_MEAN_PCT} % and ≤ {GOAL_RATIO} × forward above 1 %: {_met(goal)})")
    print(f"  ∫K predicted / target {fk:.3f} → {ok:.3f} (target {kt:+.3f}; goal within {100 * GOAL_K:.0f} %: "
          f"{_met(abs(ok - 1) <= GOAL_K)}); reached {f.reached} → {o.reached}")
    print(f"  optimization {opt.time_s:.1f} s, stage (with both layouts' predictions) {r['stage_s']:.1f} s "
          f"(goal ≤ {GOAL_S:.0f} s: {_met(r['stage_s'] <= GOAL_S)}); {opt.iterations} iterations, "
          f"{opt.evaluations} evaluations, {opt.newton_iterations} Newton iterations, {opt.stopped}; "
          f"RMS {100 * np.sqrt(opt.objective_forward):.2f} → {100 * np.sqrt(opt.objective):.2f} % on {opt.faces} faces; "
          f"τ {opt.thickness.min():.2f}-{opt.thickness.max():.2f} mm")
    design = o if r["kept"] else f
    print(f"  {'kept' if r['kept'] else 'NOT kept'} ({r['why']}); the design's predicted mean "
          f"{design.deviation_pct['mean']:.2f} %, reached {design.reached}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--surfaces", nargs="+", default=list(SURFACES), choices=SURFACES)
    args = ap.parse_args()
    load0 = os.getloadavg()
    for name in args.surfaces:
        print(f"[{name}] running ...", file=sys.stderr, flush=True)
        report(run(name))
    print(f"\nload average at the start: {', '.join(f'{x:.2f}' for x in load0)}; at the end: "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} cores (shared)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
