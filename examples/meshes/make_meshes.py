"""Write the example target surfaces (our own parametric meshes, no third-party data).

    python examples/meshes/make_meshes.py [--out DIR] [--scale N]

writes into ``examples/meshes/`` (or ``DIR``):

- ``cylinder.obj``     a 120° patch of a cylinder (radius 40 mm, height 60 mm): developable, so
                        its flattening meets the stretch bounds exactly;
- ``torus_patch.obj``  the outer part of a torus (R = 50, r = 20 mm; u ∈ [0°, 60°],
                        v ∈ [−30°, 30°]), like the paper's Fig. 2: positive Gaussian curvature,
                        within the bounds;
- ``shallow_cap.obj``  a 20° cap of a sphere of radius 80 mm: within the bounds;
- ``deep_cap.obj``     a hemisphere of radius 40 mm: outside the bounds (the fabric cannot stretch
                        that much: the design is made, and its report says so);
- ``saddle.obj``       a saddle disk (κ = ±1/50 at the centre), like the paper's octopus saddle:
                        k1 runs along one axis in two opposite quadrants and along the other
                        axis in the other two, with opposite signs, so both sides are printed.

``--scale N`` multiplies the resolution parameters (grid cells, disk rings) by N, so the face counts
grow by about N²: ``--scale 6`` gives ≥ 110,000 faces for the torus patch and the caps (benchmarks).
The sizes are in mm: ``ribbonctl design`` reads them so unless ``--size MM`` (a diagonal) or
``--size fit`` (the largest that fits the printer's frame) scales the surface.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from ribbond.design import surfaces  # noqa: E402
from ribbond.mesh.files import write_obj  # noqa: E402

HERE = Path(__file__).resolve().parent

Mesh = tuple[np.ndarray, np.ndarray]


def _res(base: int, scale: float) -> int:
    return max(1, int(round(base * scale)))


def examples(scale: float = 1.0) -> dict[str, tuple[str, Callable[[], Mesh]]]:
    """File name -> (description, builder) at resolution ``scale``."""
    return {
        "cylinder.obj": (
            "cylinder patch, radius 40, 120°, height 60 (developable)",
            lambda: surfaces.cylinder_patch(40.0, 120.0, 60.0, n_around=_res(40, scale),
                                            n_along=_res(20, scale))),
        "torus_patch.obj": (
            "torus patch R 50, r 20, u 0..60°, v -30..30° (Fig. 2)",
            lambda: surfaces.torus_patch(50.0, 20.0, u_deg=(0.0, 60.0), v_deg=(-30.0, 30.0),
                                         nu=_res(60, scale), nv=_res(30, scale))),
        "shallow_cap.obj": (
            "sphere cap, radius 80, half-angle 20° (within the bounds)",
            lambda: surfaces.sphere_cap(80.0, 20.0, rings=_res(24, scale))),
        "deep_cap.obj": (
            "hemisphere, radius 40 (outside the bounds)",
            lambda: surfaces.sphere_cap(40.0, 90.0, rings=_res(24, scale))),
        "saddle.obj": (
            "saddle disk, 80 across, κ ±1/50 (both sides printed)",
            lambda: surfaces.saddle(80.0, 1.0 / 50.0, 1.0 / 50.0, rings=_res(24, scale))),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=HERE, metavar="DIR",
                        help=f"folder to write into (default: {HERE})")
    parser.add_argument("--scale", type=float, default=1.0, metavar="N",
                        help="multiply the resolution parameters by N (faces grow by about N²)")
    args = parser.parse_args(argv)
    if not (np.isfinite(args.scale) and args.scale > 0):
        parser.error(f"--scale {args.scale}: must be a positive number")
    args.out.mkdir(parents=True, exist_ok=True)
    total = 0
    for name, (description, build) in examples(args.scale).items():
        V, F = build()
        path = args.out / name
        write_obj(path, V, F, header=f"ribbond example: {description}; scale {args.scale:g}")
        total += len(F)
        print(f"{path}: {len(F)} faces, {len(V)} vertices  ({description})")
    print(f"{total} faces in {len(examples())} files")
    return 0


if __name__ == "__main__":
    sys.exit(main())
