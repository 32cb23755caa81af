"""How far one layout's prediction can be trusted to judge a layout change (issue 34, the demo's saddle).

For each surface (the names of ``bench/realization.py``; default ``make demo``'s saddle at 90 mm) a design
is made as ``ribbonctl design --no-optimize`` makes it (``--kept``: the layout ``ribbonctl design`` keeps,
the stage optimize's line field and thicknesses), then:

- **where the realized metric loses ∫K**: ∫K of metrics that take one factor from the layout as printed
  and the rest from the flattening (``ribbond.deploy.realization``: the coverage the prediction uses,
  c = f + (1 − f)/s per line): the intended σ1, σ2 along the ribbons' own direction (the direction's
  share), the realized contraction along with the intended one across (the along share), the intended
  along with the realized across (the across share), both realized along the field (the magnitudes);
- **the noise floor**: the forward prediction of the layout, then of the same layout with one ribbon
  taken out (``--drop`` of them, chosen by a seeded generator: the same ones every run). A layout change
  whose effect on the mean, the worst release or ∫K lies within this spread is not a measured effect.

    python bench/layout_sensitivity.py [--surfaces examples/saddle ...] [--drop 6] [--kept]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))


def _design(name: str, kept: bool = False):
    """The forward design (``--no-optimize``), or with ``kept`` the layout the default design keeps (the
    stage optimize's line field and thicknesses, chosen by the prediction)."""
    from precompensate import _design as forward_design
    if not kept:
        return forward_design(name, finish=False)
    import tempfile
    from realization import _meshes
    from ribbond.design.params import DesignParameters, SizeSpec
    from ribbond.mesh.files import write_obj
    from ribbond.pipeline.compile import design_mesh
    V, F, size, _ = _meshes()[name]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{name.replace('/', '_')}.obj"
        write_obj(path, V, F)
        return design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=size)), optimize=True, finish=False)


def metric_shares(res, table) -> dict[str, float]:
    """∫K of the intended, realized and mixed metrics (see the module's docstring)."""
    from ribbond.deploy.realization import intended_metric, metric_total_curvature, realization
    from ribbond.deploy.rest_forms import contraction, rest_forms
    p, fa = res.design.parameters, res.design.faces
    sigma = np.column_stack([fa.sigma1, fa.sigma2])
    field = np.asarray(fa.ribbon_direction, dtype=float)
    s = p.prestretch
    r = realization(res.flat_uv, res.F, sigma, field, np.asarray(fa.kappa1), res.design.ribbons, prestretch=s,
                    ribbon_width=p.ribbon_width, ribbon_length=p.ribbon_length, table=table, target_V=res.V,
                    max_faces=len(res.F))
    cov = r.coverage
    c1, c2 = contraction(cov.f_along, s), contraction(cov.f_across, s)

    def K(along: np.ndarray, across: np.ndarray, d: np.ndarray) -> float:
        # intended_metric takes stretches: a contraction c is the stretch 1/c
        return metric_total_curvature(res.flat_uv, res.F, intended_metric(np.column_stack([1 / along, 1 / across]), d))

    return {"target": r.k_target, "intended": r.k_intended, "realized": metric_total_curvature(
                res.flat_uv, res.F, rest_forms(cov, s).abar),
            "intended σ, the ribbons' direction": K(1 / sigma[:, 0], 1 / sigma[:, 1], cov.direction),
            "realized along, intended across": K(c1, 1 / sigma[:, 1], field),
            "intended along, realized across": K(1 / sigma[:, 0], c2, field),
            "realized along and across, the field's direction": K(c1, c2, field)}


def predictions(res, table, drop: int) -> list[dict]:
    """The forward prediction of the layout and of ``drop`` copies less one ribbon each (seeded)."""
    from ribbond.deploy.predict import predict_deployed
    p, ribbons = res.design.parameters, list(res.design.ribbons)
    rng = np.random.default_rng(34)
    out = []
    for k in [None, *rng.choice(len(ribbons), size=min(drop, len(ribbons)), replace=False)]:
        kept = ribbons if k is None else ribbons[:k] + ribbons[k + 1:]
        pr = predict_deployed(res.flat_uv, res.V, res.F, kept, prestretch=p.prestretch,
                              ribbon_width=p.ribbon_width, table=table)
        a = pr.agreement
        out.append({"without": k, "mean": pr.deviation_pct["mean"], "worst": a.spread_mean[1],
                    "K": a.curvature_predicted, "Kt": a.curvature_target, "reached": pr.reached})
    return out


#: Below this |∫K| a target is nearly developable: ∫K is printed as it is, not as a share (as ``agreement``).
NEARLY_DEVELOPABLE = 0.1


def _K(value: float, target: float) -> str:
    if abs(target) <= NEARLY_DEVELOPABLE:
        return f"{value:+.3f}"
    return f"{100 * value / target:.0f} %"


def _K_range(values: list[float], target: float) -> str:
    if abs(target) <= NEARLY_DEVELOPABLE:
        return f"{min(values):+.3f} to {max(values):+.3f}"
    shares = [100 * v / target for v in values]
    return f"{min(shares):.0f}–{max(shares):.0f} %"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--surfaces", nargs="*", default=["examples/saddle"])
    ap.add_argument("--drop", type=int, default=6, help="layouts less one ribbon to predict")
    ap.add_argument("--kept", action="store_true", help="the layout the default design keeps (optimize on)")
    args = ap.parse_args()
    from ribbond.design.thickness import load_curvature_table
    for name in args.surfaces:
        res = _design(name, args.kept)
        table = load_curvature_table(res.design.parameters.curvature_table)
        print(f"\n{name}: {len(res.design.ribbons)} ribbons")
        shares = metric_shares(res, table)
        for key, value in shares.items():
            print(f"  ∫K {key:<50} {value:+.3f} ({_K(value, shares['target'])} of the target's)")
        rows = predictions(res, table, args.drop)
        for r in rows:
            what = "the layout" if r["without"] is None else f"less ribbon {r['without']}"
            print(f"  {what:<18} mean {r['mean']:.2f} %, worst release {r['worst']:.2f} %, "
                  f"∫K {_K(r['K'], r['Kt'])}, reached {r['reached']}")
        less = rows[1:]
        if less:
            print(f"  less one ribbon: mean {min(r['mean'] for r in less):.2f}–{max(r['mean'] for r in less):.2f} %, "
                  f"worst release {min(r['worst'] for r in less):.2f}–{max(r['worst'] for r in less):.2f} %, "
                  f"∫K {_K_range([r['K'] for r in less], less[0]['Kt'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
