"""Benchmark of the realization (issue 34): does the printed plastic carry the metric and curvature the
flattening asked for, and does the layout then take the target's shape?

For each surface (a cylinder, the torus patch of Fig. 2, a symmetric and a skew saddle, a shallow cap,
each 100–120 mm, and the meshes of ``examples/meshes/`` at ``make demo``'s size) a design is made as
``ribbonctl design`` makes it (default parameters, the prediction apart), then:

- ``report.realization`` (``ribbond.deploy.realization``), each figure against the issue's goal, and ∫K
  of the intended and of the realized metric against the target's:
  along and across, median within ±1 % and p5–p95 within ±5 % (interior faces); the plastic area within
  3 % (relative) of Eq. 10's; bare faces ≤ 0.5 %; the rest curvature's median within 5 % of |κ1| where
  the table's range allows;
- the forward prediction of the layout (the homogenized model, released from the flat sheet): mean
  deviation (goal ≤ 1.5 % on the feasible surfaces), ∫K predicted / target, ``reached``;
- the same layout predicted with the flattening's intended metric Ā = d dᵀ/σ1² + d⊥ d⊥ᵀ/σ2² in place of
  the realized one (stiffness, curvature table and release path unchanged): what a perfect realization
  gives; goal: the two within 0.3 points of mean deviation on the feasible surfaces.

    python bench/realization.py [--surfaces cylinder saddle ...] [--no-predict]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

GOAL_MEDIAN = 1.0
GOAL_SPAN = 5.0
GOAL_PLASTIC = 3.0
GOAL_BARE = 0.5
GOAL_CURVATURE = 5.0
GOAL_MEAN = 1.5
GOAL_GAP = 0.3


def _meshes() -> dict:
    """name -> (V, F, size mm, feasible)."""
    from ribbond.design import surfaces
    out = {
        "cylinder": (*surfaces.cylinder_patch(n_around=100, n_along=50), 100.0, True),
        "torus_patch": (*surfaces.torus_patch(nu=100, nv=50), 120.0, True),
        "saddle": (*surfaces.saddle(size=80.0, kappa_x=1 / 40.0, kappa_y=1 / 40.0, rings=40), 110.0, True),
        "skew_saddle": (*surfaces.saddle(size=80.0, kappa_x=1 / 35.0, kappa_y=1 / 80.0, rings=40), 110.0, True),
        "shallow_cap": (*surfaces.sphere_cap(radius=80.0, half_angle_deg=25.0, rings=40), 100.0, True),
    }
    sys.path.insert(0, str(ROOT / "examples" / "meshes"))
    import make_meshes
    for file, (_, build) in make_meshes.examples().items():
        V, F = build()
        name = Path(file).stem
        out[f"examples/{name}"] = (V, F, 90.0, name != "deep_cap")
    return out


def intended_sheet_factory(design_uv, design_F, sigma, direction):
    """``predict.sheet_for_layout`` with Ā replaced by the flattening's intended metric, read at each
    face of the prediction's mesh from the design face its centroid lies in."""
    from ribbond.deploy import predict
    from ribbond.deploy.realization import intended_metric
    from ribbond.design.remesh import locate
    plain = predict.sheet_for_layout

    def sheet_for_layout(uv, F, ribbons, **kw):
        sheet, cov = plain(uv, F, ribbons, **kw)
        face, _ = locate(uv[F].mean(axis=1), design_uv, design_F)
        abar = intended_metric(sigma[face], direction[face])
        return dataclasses.replace(sheet, abar=abar), cov
    return sheet_for_layout


def _predict(res, kw, intended: bool):
    from ribbond.deploy import predict
    fa = res.design.faces
    plain = predict.sheet_for_layout
    if intended:
        sig = np.column_stack([fa.sigma1, fa.sigma2])
        predict.sheet_for_layout = intended_sheet_factory(res.flat_uv, res.F, sig, np.asarray(fa.ribbon_direction))
    try:
        return predict.predict_deployed(res.flat_uv, res.V, res.F, res.design.ribbons, **kw)
    finally:
        predict.sheet_for_layout = plain


def run(name: str, V, F, size: float, feasible: bool, do_predict: bool) -> dict:
    from ribbond.mesh.files import write_obj
    from ribbond.design.params import DesignParameters, SizeSpec
    from ribbond.pipeline.compile import design_mesh
    from ribbond.design.thickness import load_curvature_table
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / (name.replace("/", "_") + ".obj")
        write_obj(path, V, F)
        t0 = time.perf_counter()
        res = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=size)), predict=False, finish=False)
        t_design = time.perf_counter() - t0
    r = {"name": name, "feasible": feasible, "faces": len(res.F), "ribbons": len(res.design.ribbons),
         "design_s": t_design, "real": res.design.report.realization.model_dump(),
         "bad": max(res.design.report.sigma1_bad_pct, res.design.report.sigma2_bad_pct)}
    if do_predict:
        p = res.design.parameters
        kw = dict(prestretch=p.prestretch, ribbon_width=p.ribbon_width, table=load_curvature_table(p.curvature_table))
        for key, intended in (("forward", False), ("intended", True)):
            pr = _predict(res, kw, intended)
            a = pr.agreement
            r[key] = {"mean": pr.deviation_pct["mean"], "worst": a.spread_mean[1], "reached": pr.reached,
                      "K": a.curvature_predicted / a.curvature_target if abs(a.curvature_target) > 0.1 else None,
                      "Kp": a.curvature_predicted, "Kt": a.curvature_target,
                      "time_s": pr.time_s}
    return r


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _spread(q: dict | None) -> str:
    return "—" if q is None else f"{q['median']:+.2f} ({q['p5']:+.2f}…{q['p95']:+.2f})"


def report(r: dict) -> None:
    q = r["real"]
    print(f"\n{r['name']} ({r['faces']} faces, {r['ribbons']} ribbons, design {r['design_s']:.1f} s, "
          f"{r['bad']:.1f} % of faces outside the bounds{'' if r['feasible'] else '; infeasible'})")
    for key in ("along_pct", "across_pct"):
        s = q[key]
        ok = s is not None and abs(s["median"]) <= GOAL_MEDIAN and max(abs(s["p5"]), abs(s["p95"])) <= GOAL_SPAN
        print(f"  {key[:-4]:<7} interior {_spread(s)} %  [goal median ±{GOAL_MEDIAN}, p5–p95 ±{GOAL_SPAN}: "
              f"{_met(ok)}]; near the outline {_spread(q[key + '_outline'])} %")
    pl = q["plastic_pct"]
    rel = 100 * (pl["printed"] / pl["eq10"] - 1) if pl["eq10"] else 0.0
    print(f"  plastic {pl['printed']:.2f} % of the flat area, Eq. 10 asks {pl['eq10']:.2f} % ({rel:+.1f} %) "
          f"[goal ±{GOAL_PLASTIC} %: {_met(abs(rel) <= GOAL_PLASTIC)}]; bare faces {q['bare_pct']:.2f} % "
          f"[goal ≤ {GOAL_BARE}: {_met(q['bare_pct'] <= GOAL_BARE)}]")
    c = q["curvature_pct"]
    print(f"  rest curvature vs |κ1| {_spread(c)} % [goal median ±{GOAL_CURVATURE}: "
          f"{_met(c is not None and abs(c['median']) <= GOAL_CURVATURE)}]; {q['clamped_pct']:.1f} % of ribbons "
          f"at the table's limits")
    K = q["total_gaussian_curvature"]
    big = abs(K["target"]) > 0.1
    ratio = f" ({K['intended'] / K['target']:.2f})" if big else " (nearly developable)"
    real = f" ({K['realized'] / K['target']:.2f})" if big else ""
    print(f"  ∫K intended {K['intended']:+.3f} / target {K['target']:+.3f}{ratio}; the realized metric's "
          f"{K['realized']:+.3f}{real}")
    if "forward" in r:
        f, i = r["forward"], r["intended"]
        gap = f["mean"] - i["mean"]
        goal = (f" [goal ≤ {GOAL_MEAN} % and reached: {_met(f['mean'] <= GOAL_MEAN and f['reached'])}; gap to "
                f"the intended metric ≤ {GOAL_GAP}: {_met(abs(gap) <= GOAL_GAP)}]") if r["feasible"] else ""
        for key, d in (("predicted", f), ("intended metric", i)):
            k = f"∫K {d['Kp']:+.2f} (target {d['Kt']:+.2f})" if d["K"] is None else f"∫K {100 * d['K']:.0f} % of the target's"
            print(f"  {key:<16} mean {d['mean']:.2f} % (worst release {d['worst']:.2f} %), {k}, "
                  f"reached {d['reached']}, {d['time_s']:.1f} s")
        print(f"  gap {gap:+.2f} points{goal}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--surfaces", nargs="*", help="names (default: all)")
    ap.add_argument("--no-predict", action="store_true", help="the realization only")
    args = ap.parse_args()
    meshes = _meshes()
    names = args.surfaces or list(meshes)
    for name in names:
        V, F, size, feasible = meshes[name]
        report(run(name, V, F, size, feasible, not args.no_predict))
    return 0


if __name__ == "__main__":
    sys.exit(main())
