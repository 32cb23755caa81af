"""Benchmark of the deployed-shape prediction (ribbond.deploy, issue 23) on four analytic surfaces.

For each surface (a cylinder patch, the torus patch of the paper's Fig. 2, a symmetric saddle disk and a
hemisphere; sizes are bounding-box diagonals: 100, 120, 110, 100 mm; ~10k faces each) a fresh
subprocess designs it as ``ribbonctl design`` does (default parameters at the bench size,
``design_mesh(predict=False)``), then predicts the deployed shape of the layout and reports, each against its goal:

- the deploy stage (homogenized model, nominal release and the spread's other releases): time (≤ 30 s),
  deviation mean / p99 / max and its spread (% of the target's diagonal), ∫K predicted / target, area
  ratio, ``reached``;
- convergence: the nominal prediction at twice the reference resolution against the default, registered
  (Kabsch), mean distance % of the diagonal (≤ 0.5 %); the nominal release in 10, 20 and 40 steps, the
  largest mean distance between any two (≤ 0.3 %);
Each ``deployed.png`` is written to ``--out`` (default ``bench/out/deploy``). The layout optimized
against the prediction has its own bench: ``bench/optimize.py``.

    python bench/deploy.py [--surfaces cylinder saddle] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

RESULT_TAG = "BENCH-DEPLOY "
#: name -> (mesh maker, bounding-box diagonal mm, feasible)
SURFACES = ("cylinder", "torus_patch", "saddle", "hemisphere")
FEASIBLE = {"cylinder": True, "torus_patch": True, "saddle": True, "hemisphere": False}
GOAL_DEPLOY_S = 30.0
GOAL_RES_PCT = 0.5
GOAL_STEPS_PCT = 0.3


def _mesh(name: str):
    """(V, F, bbox diagonal mm) of a bench surface, ~10k faces: more than 1.25 × 2 × DEFAULT_FACES, so
    that the default and the doubled reference meshes are both remeshes of the flat domain."""
    from ribbond.design import surfaces
    if name == "cylinder":
        return (*surfaces.cylinder_patch(n_around=100, n_along=50), 100.0)
    if name == "torus_patch":
        return (*surfaces.torus_patch(nu=100, nv=50), 120.0)
    # sizes as bounding-box diagonals (the engine's ``size``), as tests/deploy/test_predict.py: a
    # hemisphere 100 mm across (diagonal 150 mm) flattens to 172 mm, more than the frame takes
    if name == "saddle":                                   # symmetric: κx = κy
        return (*surfaces.saddle(size=80.0, kappa_x=1 / 40.0, kappa_y=1 / 40.0, rings=40), 110.0)
    if name == "hemisphere":
        return (*surfaces.sphere_cap(radius=50.0, half_angle_deg=90.0, rings=40), 100.0)
    raise ValueError(f"unknown surface {name!r}")


def _design(name: str, workdir: Path):
    from ribbond.mesh.files import write_obj
    from ribbond.design.params import DesignParameters, SizeSpec
    from ribbond.pipeline.compile import design_mesh
    from ribbond.design.thickness import load_curvature_table
    V, F, size = _mesh(name)
    path = workdir / f"{name}.obj"
    write_obj(path, V, F)
    res = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=size)), predict=False)
    params = res.design.parameters
    kw = dict(prestretch=params.prestretch, ribbon_width=params.ribbon_width,
              table=load_curvature_table(params.curvature_table))
    return res, kw


def registered_distance_pct(a, b, diagonal: float) -> float:
    """Mean distance, % of ``diagonal``, between prediction b and prediction a interpolated at b's flat
    positions, after a rigid registration (Kabsch) of the one onto the other."""
    from ribbond.deploy.compare import kabsch
    from ribbond.deploy.predict import interpolate
    A = interpolate(b.uv, a.uv, a.F, a.V)
    R, t = kabsch(A, b.V)
    return float(100.0 * np.linalg.norm(A @ R.T + t - b.V, axis=1).mean() / diagonal)


def _summary(p) -> dict:
    a = p.agreement
    return {"time_s": p.time_s, "faces": p.faces, "iterations": p.iterations, "converged": p.converged,
            "deviation": p.deviation_pct, "spread_mean": list(a.spread_mean),
            "K": [a.curvature_predicted, a.curvature_target], "area_ratio": a.area_ratio,
            "reached": p.reached, "verdict": p.verdict}


def child(name: str, out: Path) -> int:
    """Design ``name`` (forward: ``design_mesh(predict=False)``), predict its layout; print one tagged JSON line."""
    from ribbond.deploy.predict import predict_deployed
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        res, kw = _design(name, Path(tmp))
    uv, V, F, rib = res.flat_uv, res.V, res.F, res.design.ribbons
    diagonal = float(np.linalg.norm(np.ptp(V, axis=0)))
    r: dict = {"surface": name, "design_faces": len(F), "ribbons": len(rib), "diagonal": diagonal}
    home = predict_deployed(uv, V, F, rib, **kw)
    r["homogenized"] = _summary(home)
    (out / f"{name}_homogenized.png").write_bytes(home.render_png(V, F, title=f"{name}: homogenized"))
    r["convergence"] = _convergence(uv, V, F, rib, kw, home, diagonal)
    r["peak_rss_kb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(RESULT_TAG + json.dumps(r), flush=True)
    return 0


def _convergence(uv, V, F, rib, kw, home, diagonal: float) -> dict:
    """Twice the reference resolution against the default; the nominal release in 10, 20, 40 steps."""
    from ribbond.deploy.predict import DEFAULT_FACES, predict_deployed
    from ribbond.deploy.release import NOMINAL
    fine2 = predict_deployed(uv, V, F, rib, target_faces=2 * DEFAULT_FACES, releases=(NOMINAL,), **kw)
    nominal = predict_deployed(uv, V, F, rib, releases=(NOMINAL,), **kw)
    by_steps = {s: (nominal if s == 10 else predict_deployed(uv, V, F, rib, steps=s, releases=(NOMINAL,), **kw))
                for s in (10, 20, 40)}
    pairs = {f"{a}-{b}": registered_distance_pct(by_steps[a], by_steps[b], diagonal)
             for a, b in ((10, 20), (20, 40), (10, 40))}
    return {"double_faces": fine2.faces, "double_vs_default_pct": registered_distance_pct(nominal, fine2, diagonal),
            "steps_pct": pairs, "steps_time_s": {s: p.time_s for s, p in by_steps.items()}}


def run_child(name: str, out: Path) -> dict:
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", name, str(out)],
                          capture_output=True, text=True, cwd=ROOT)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_TAG)]
    if proc.returncode != 0 or not lines:
        tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-25:])
        raise RuntimeError(f"{name} failed (exit code {proc.returncode}):\n{tail}")
    return json.loads(lines[-1][len(RESULT_TAG):])


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def report(r: dict) -> None:
    """Print one child's figures, each with its goal."""
    name, h = r["surface"], r["homogenized"]
    dv, K = h["deviation"], h["K"]
    print(f"\n{name} ({r['design_faces']} design faces, {r['ribbons']} ribbons, diagonal {r['diagonal']:.1f} mm)")
    print(f"  deploy stage (homogenized, nominal + spread): {h['time_s']:.1f} s (goal ≤ {GOAL_DEPLOY_S:.0f} s: "
          f"{_met(h['time_s'] <= GOAL_DEPLOY_S)}); {h['faces']} faces, {h['iterations']} Newton iterations, "
          f"converged {h['converged']}")
    print(f"  deviation mean / p99 / max {dv['mean']:.2f} / {dv['p99']:.2f} / {dv['max']:.2f} %, "
          f"spread of the mean {h['spread_mean'][0]:.2f}-{h['spread_mean'][1]:.2f} %; "
          f"∫K {K[0]:+.2f} / target {K[1]:+.2f}; area ratio {h['area_ratio']:.3f}; reached {h['reached']}")
    print(f"  verdict: {h['verdict']}")
    c = r["convergence"]
    print(f"  2× resolution ({c['double_faces']} faces) against the default: {c['double_vs_default_pct']:.2f} % "
          f"(goal ≤ {GOAL_RES_PCT} %: {_met(c['double_vs_default_pct'] <= GOAL_RES_PCT)})")
    worst = max(c["steps_pct"].values())
    print(f"  steps 10/20/40: " + ", ".join(f"{k} {v:.2f} %" for k, v in c["steps_pct"].items())
          + f" (goal ≤ {GOAL_STEPS_PCT} %: {_met(worst <= GOAL_STEPS_PCT)}); nominal times "
          + ", ".join(f"{k} steps {v:.1f} s" for k, v in c["steps_time_s"].items()))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--surfaces", nargs="+", default=list(SURFACES), choices=SURFACES)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "out" / "deploy")
    ap.add_argument("--child", nargs=2, metavar=("SURFACE", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        return child(args.child[0], Path(args.child[1]))
    load0 = os.getloadavg()
    failures = []
    for name in args.surfaces:
        print(f"[{name}] running ...", file=sys.stderr, flush=True)
        try:
            report(run_child(name, args.out))
        except RuntimeError as exc:
            failures.append(str(exc))
            print(f"\n{name}: FAILED", flush=True)
    print(f"\nload average (1, 5, 15 min) at the start: {', '.join(f'{x:.2f}' for x in load0)}; at the end: "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} cores "
          "(shared: read the times with it)")
    print(f"pictures: {args.out}")
    if failures:
        print("\n" + "\n\n".join(failures), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
