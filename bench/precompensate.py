"""The σ pre-compensation of issue 34 item 4, measured: lay out, realize, correct the σ the layout
follows, lay out again, and predict both layouts from the flat sheet.

For each surface (``bench/realization.py``'s, by name) the forward design is made as ``ribbonctl
design --no-predict`` makes it; then, round after round, the layout's stripes and ribbons are made
again (``stripe_grid``, ``layout_ribbons``, the table's thicknesses: the pipeline's own calls) for a
corrected σ, and measured with ``realization`` against the flattening's σ (the intended metric, never
the corrected one). Two corrections of the contraction c = 1/σ the layout is asked for:

- ``global``: per direction, c_layout = c_intended · g, g divided by (1 + the interior median error)
  each round (what a systematic shortfall needs);
- ``local``: per face, c_layout += gain (c_intended − c_realized), the realized c mapped from the
  measured faces to the nearest, clipped to ± ``clip`` of c_intended and to c ≤ 1.

It prints each round's realization (along, across: median and p5–p95 of the interior faces; plastic
printed against Eq. 10's; ribbons) and, with ``--predict``, the forward and the best round's predicted
mean deviation, worst release, ∫K and ``reached``: whether realizing the intended metric's medians
better brings the predicted shape closer.

    python bench/precompensate.py torus_patch saddle [--mode global|local] [--rounds 3] [--predict]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))


def _design(name: str, finish: bool = True):
    """The forward design of a bench surface (``realization._meshes``), without its prediction."""
    from realization import _meshes
    from ribbond.mesh.files import write_obj
    from ribbond.design.params import DesignParameters, SizeSpec
    from ribbond.pipeline.compile import design_mesh
    V, F, size, _ = _meshes()[name]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{name.replace('/', '_')}.obj"
        write_obj(path, V, F)
        return design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=size)), predict=False,
                           finish=finish)


class _Relayout:
    """The pipeline's stripes → ribbons → thicknesses for a given σ, and the realization against the
    flattening's σ."""

    def __init__(self, res) -> None:
        from ribbond.design.params import DesignParameters, SolverSettings
        from ribbond.design.thickness import load_curvature_table
        self.res, P = res, res.design.parameters
        keys = ("prestretch", "ribbon_length", "ribbon_width", "sigma1_bounds", "sigma2_bounds",
                "min_ribbon_length", "max_trim_angle")
        self.params = DesignParameters(**{k: getattr(P, k) for k in keys})
        self.solver, self.table = SolverSettings(), load_curvature_table(P.curvature_table)

    def ribbons(self, sigma: np.ndarray) -> list:
        import shapely
        from ribbond.pipeline.compile import _ribbons
        from ribbond.design.ribbons import layout_ribbons, stripe_grid
        r, sv = self.res, self.solver
        grid = stripe_grid(r.flat_uv, r.F, r.target.boundary, sigma, r.ribbon_direction, r.kappa1, self.params,
                           edge_fraction=sv.stripe_edge_fraction, max_faces=sv.stripe_max_faces,
                           spacing_weight=sv.stripe_spacing_weight, direction_weight=sv.stripe_direction_weight)
        layout = layout_ribbons(grid, shapely.Polygon(r.flat_uv[r.target.boundary]), self.params)
        return _ribbons(layout, self.table)[0]

    def measure(self, ribbons: list):
        from ribbond.deploy.realization import realization
        r, p = self.res, self.params
        return realization(r.flat_uv, r.F, r.flattening.sigma, r.ribbon_direction, r.kappa1, ribbons,
                           prestretch=p.prestretch, ribbon_width=p.ribbon_width, ribbon_length=p.ribbon_length,
                           table=self.table, target_V=r.V)


def _corrected(mode: str, c_int: np.ndarray, c_lay: np.ndarray, real, centroid: np.ndarray, s: float,
               gain: float, clip: float) -> np.ndarray:
    from scipy.spatial import cKDTree
    from ribbond.deploy.rest_forms import contraction
    if mode == "global":
        med = np.array([np.median(real.along[real.interior]), np.median(real.across[real.interior])])
        return np.minimum(c_lay / (1.0 + med / 100.0), 1.0)
    cr = np.column_stack([contraction(real.coverage.f_along, s), contraction(real.coverage.f_across, s)])
    idx = cKDTree(centroid[real.faces]).query(centroid)[1]
    return np.clip(c_lay + gain * (c_int - cr[idx]), (1 - clip) * c_int, np.minimum((1 + clip) * c_int, 1.0))


def run(name: str, mode: str, rounds: int, gain: float, clip: float, predict: bool) -> None:
    res = _design(name)
    lay = _Relayout(res)
    s = lay.params.prestretch
    c_int = 1.0 / res.flattening.sigma
    c_lay, best = c_int.copy(), None
    centroid = res.flat_uv[res.F].mean(axis=1)
    print(f"\n{name} ({mode})")
    for k in range(rounds + 1):
        rib = lay.ribbons(1.0 / c_lay)
        real = lay.measure(rib)
        rep = real.report()
        score = float(np.mean(np.abs(real.along[real.interior])) + np.mean(np.abs(real.across[real.interior])))
        a, c, pl = rep["along_pct"] or {}, rep["across_pct"] or {}, rep["plastic_pct"]
        print(f"  round {k}: along {a.get('median')} ({a.get('p5')}…{a.get('p95')}) %, across {c.get('median')} "
              f"({c.get('p5')}…{c.get('p95')}) %, plastic {pl['printed']} / {pl['eq10']} %, {len(rib)} ribbons, "
              f"mean |error| {score:.2f} %", flush=True)
        if k == 0:
            forward = rib
        elif best is None or score < best[0]:
            best = (score, rib, k)
        if k < rounds:
            c_lay = _corrected(mode, c_int, c_lay, real, centroid, s, gain, clip)
    if predict and best is not None:
        from ribbond.deploy.predict import predict_deployed
        kw = dict(prestretch=s, ribbon_width=lay.params.ribbon_width, table=lay.table)
        for label, rib in (("forward", forward), (f"round {best[2]}", best[1])):
            p = predict_deployed(res.flat_uv, res.V, res.F, rib, **kw)
            g = p.agreement
            print(f"  predicted, {label}: mean {p.deviation_pct['mean']:.2f} %, worst release {g.spread_mean[1]:.2f} %, "
                  f"∫K {100 * g.curvature_predicted / g.curvature_target:.0f} % of the target's, reached {p.reached}",
                  flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("surfaces", nargs="+", help="names of bench/realization.py's surfaces")
    ap.add_argument("--mode", choices=("global", "local"), default="global")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--gain", type=float, default=0.5, help="local: share of the error corrected per round")
    ap.add_argument("--clip", type=float, default=0.1, help="local: largest correction, share of c")
    ap.add_argument("--predict", action="store_true")
    args = ap.parse_args()
    for name in args.surfaces:
        run(name, args.mode, args.rounds, args.gain, args.clip, args.predict)
    return 0


if __name__ == "__main__":
    sys.exit(main())
