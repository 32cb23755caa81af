"""Benchmark of the line-field choice of the stage optimize and of the rim rows (issue 34): on a saddle
with |κ1| ≈ |κ2| the paper's field (largest |κ|) switches family on the H = 0 diagonals and its rows make
corners; one family of curvature lines through the region (``ribbond.design.saddle_family``) makes none.
Where rows run along a bare rim and the plastic falls short there, a row follows the outline
(``ribbond.design.rim``).

For each surface (``make demo``'s saddle at 90 mm; the symmetric saddle, the skew saddle, the cylinder,
the torus patch and the shallow cap of ``bench/realization.py``, where no alternative field is made and
the rim must not be laid where the pattern already carries the outline) it runs the pipeline as
``ribbonctl design`` does (the prediction and the optimization on) and prints:

- the share of the saddle regions' area where one family leaves the paper's k1;
- each field's forward layout predicted from the flat sheet (mean deviation, worst release, ∫K kept),
  which one the rule kept (``optimization_kept``), and why;
- the rim rows laid and the short pieces they replaced;
- the design's final prediction (after the thickness optimization), ``reached``, the optimize stage's
  time (the alternative's design and prediction are in it).

    python bench/field_choice.py [--surfaces demo_saddle saddle ...]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _meshes() -> dict:
    """name -> (V, F, size mm)."""
    from ribbond.design import surfaces
    return {"demo_saddle": (*surfaces.saddle(80.0, 1 / 50.0, 1 / 50.0, rings=24), 90.0),
            "saddle": (*surfaces.saddle(size=80.0, kappa_x=1 / 40.0, kappa_y=1 / 40.0, rings=40), 110.0),
            "skew_saddle": (*surfaces.saddle(size=80.0, kappa_x=1 / 35.0, kappa_y=1 / 80.0, rings=40), 110.0),
            "cylinder": (*surfaces.cylinder_patch(n_around=100, n_along=50), 100.0),
            "torus_patch": (*surfaces.torus_patch(nu=100, nv=50), 120.0),
            "shallow_cap": (*surfaces.sphere_cap(radius=80.0, half_angle_deg=25.0, rings=40), 100.0)}


def _shape(s) -> str:
    k = s.total_gaussian_curvature
    return (f"mean {s.deviation_pct.mean:.2f} %, ∫K {k.predicted:+.2f} ({100 * k.predicted / k.target:.0f} % "
            f"of the target's {k.target:+.2f})")


def run(name: str, V, F, size: float) -> None:
    from ribbond.design.params import DesignParameters, SizeSpec
    from ribbond.mesh.files import write_obj
    from ribbond.pipeline.compile import design_mesh
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{name}.obj"
        write_obj(path, V, F)
        t0 = time.perf_counter()
        res = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=size)), optimize=True, finish=False)
        total = time.perf_counter() - t0
    r = res.design.report
    o, d = r.optimization, r.deployed
    print(f"\n{name} ({len(res.F)} faces, {size:.0f} mm; design {total:.1f} s, of which optimize "
          f"{r.timings_s['optimize']:.1f} s)")
    c = o.line_field if o is not None else None
    if c is None:
        print("  no ambiguous saddle region switches family: the paper's field, no alternative made")
    else:
        print(f"  one family leaves the paper's k1 on {c.switched_pct:.1f} % of the saddle regions' area")
        print(f"  paper's field      {_shape(c.paper)}")
        print(f"  one family         {_shape(c.one_family) if c.one_family else 'not made'}")
        print(f"  kept: {c.kept} ({c.reason})")
    rr = r.ribbons
    print(f"  rim: {rr.rim} rows along the outline, replacing {rr.rim_replaced} short pieces")
    sides = {rb.side for rb in res.design.ribbons}
    print(f"  the design: {len(res.design.ribbons)} ribbons on {' and '.join(sorted(sides))}; "
          f"thickness optimization {'kept' if o is not None and o.kept else 'not kept'}; predicted mean "
          f"{d.deviation_pct.mean:.2f} % (worst release {d.spread.mean[1]:.2f} %), ∫K {d.total_gaussian_curvature.predicted:+.2f} "
          f"/ {d.total_gaussian_curvature.target:+.2f}, reached {d.reached}")


def main() -> int:
    meshes = _meshes()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--surfaces", nargs="+", default=list(meshes), choices=list(meshes))
    args = ap.parse_args()
    for name in args.surfaces:
        run(name, *meshes[name])
    return 0


if __name__ == "__main__":
    sys.exit(main())
