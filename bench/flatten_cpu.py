"""The flattening of the scanned-style meshes in CPU time, paired with libigl's ARAP iteration.

On a 2-core machine shared with other work the wall times of ``bench/flatten.py`` move by several
times between runs (and libigl's C++ iteration suffers less from the load than ours); the process
time of both, on the same mesh in the same process, is a steadier ratio. Each surface: the coarse
mesh of ``bench/flatten.py``'s ``scanned_*`` refined as the intake refines it (``refine``, three
rounds, two with --quick), scaled to a 110 mm diagonal, its curvature line field, then the
flattening (set-up and solve, as the pipeline's flatten stage runs them) and 10 iterations of
``igl.arap_solve`` (elements energy) from the flattener's Tutte + SLIM start.

    python bench/flatten_cpu.py [--quick] [--surfaces saddle,cap,torus]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import igl
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flatten import COARSE, levels  # noqa: E402  (bench/flatten.py, the same coarse meshes)

from ribbond.design.curvature import face_curvature  # noqa: E402
from ribbond.design.flatten import BoundedFlattener  # noqa: E402
from ribbond.design.frames import face_frames  # noqa: E402
from ribbond.design.line_field import ANISOTROPY_THRESHOLD, curvature_line_field  # noqa: E402
from ribbond.design.params import DesignParameters, SizeSpec, SolverSettings  # noqa: E402
from ribbond.design.refine import refine  # noqa: E402


def measure(name: str, scale: float) -> dict[str, float]:
    """CPU seconds of the flattening and of one libigl ARAP iteration on the refined ``name``."""
    fine = refine(*COARSE[name](), levels(scale))
    V = fine.V - fine.V.mean(axis=0)
    V *= 110.0 / np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    F = fine.F
    frames = face_frames(V, F)
    field = curvature_line_field(V, F, frames, face_curvature(V, F, frames))
    params = DesignParameters(size=SizeSpec(bbox_diagonal=110.0))
    c0 = time.process_time()
    flattener = BoundedFlattener(V, F, field.angle, params.bounds, SolverSettings(), frames=frames,
                                 prestretch=params.prestretch,
                                 k1_defined=field.anisotropy > ANISOTROPY_THRESHOLD)
    flat = flattener.solve()
    ours = time.process_time() - c0
    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_ELEMENTS
    data.max_iter = 1
    pinned = np.array([0], dtype=np.int32)
    igl.arap_precomputation(np.ascontiguousarray(V), np.ascontiguousarray(F, dtype=np.int64), 2, pinned, data)
    U = np.ascontiguousarray(flattener.initial_map())
    bc = U[pinned].copy()
    U = igl.arap_solve(bc, data, U)                                   # warm-up
    c1 = time.process_time()
    for _ in range(10):
        U = igl.arap_solve(bc, data, U)
    igl_per_iteration = (time.process_time() - c1) / 10
    return {"faces": len(F), "iterations": flat.iterations, "cpu_s": ours,
            "igl_ms": 1000 * igl_per_iteration, "arap_eq": ours / igl_per_iteration}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="two rounds of refinement instead of three")
    ap.add_argument("--surfaces", default="saddle,cap", help=f"comma-separated, from {', '.join(COARSE)}")
    args = ap.parse_args()
    names = [s for s in args.surfaces.split(",") if s]
    unknown = set(names) - set(COARSE)
    if unknown:
        ap.error(f"unknown surfaces: {', '.join(sorted(unknown))}")
    print(f"{'surface':<16} {'faces':>7} {'iter':>5} {'CPU s':>6} {'igl CPU ms/it':>13} {'ARAP-eq':>7}")
    for name in names:
        r = measure(name, 0.5 if args.quick else 1.0)
        print(f"scanned_{name:<8} {r['faces']:>7} {r['iterations']:>5} {r['cpu_s']:>6.2f} {r['igl_ms']:>13.1f} "
              f"{r['arap_eq']:>7.0f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
