"""Benchmark of the deployed-shape prediction (ribbond.deploy, issue 12) on the bench surfaces.

For each surface (the torus patch of the paper's Fig. 2 and the saddle disk of ``examples/meshes``,
as ``bench/design.py`` makes them) and each size, one fresh subprocess runs ``design_mesh`` as
``ribbonctl design`` does (default parameters, size left to the printer's frame, with its ``deploy``
stage), and reports the prediction's time, its Newton iterations, the
mesh it ran on, the deviation, the rest of the engine's time (the sum of ``report.timings_s``) and
the process's peak resident memory (the whole design with the prediction).

Goals: the prediction ≤ 10 s at the default resolution on 2 cores; ≤ 1× the rest of the engine;
the whole design with prediction ≤ 2 GB at 160k faces.

    python bench/deploy.py [--quick] [--sizes 10000 160000] [--surfaces torus_patch saddle]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "examples" / "meshes"))
sys.path.insert(0, str(ROOT / "bench"))

import design as design_bench  # noqa: E402  (bench/design.py: the meshes and the child runs)
from design import write_meshes  # noqa: E402

SIZES = (10_000, 40_000, 160_000)
SURFACES = ("torus_patch", "saddle")
GOAL_S = 10.0
GOAL_RATIO = 1.0
GOAL_MB = 2048.0
RESULT_TAG = design_bench.RESULT_TAG


def child(mesh: Path) -> int:
    """Design ``mesh``, predict its deployed shape, print one tagged JSON line."""
    from ribbond.design.params import DesignParameters, SolverSettings
    from ribbond.design.pipeline import design_mesh

    result = design_mesh(mesh, DesignParameters(), SolverSettings())     # with its deploy stage
    rep = result.design.report
    p = result.prediction
    timings = dict(rep.timings_s)
    wall = timings.pop("deploy")
    out = {
        "faces": rep.faces,
        "engine_s": float(sum(timings.values())),
        "timings": timings,
        "predict_s": wall,
        "iterations": p.iterations,
        "start": p.start,
        "converged": p.converged,
        "predict_faces": p.faces,
        "ribbons": len(result.design.ribbons),
        "deviation": p.deviation_pct,
        "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
    }
    print(RESULT_TAG + json.dumps(out), flush=True)
    return 0


def run_child(mesh: Path) -> dict:
    return design_bench.run_child(mesh, Path(__file__))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), metavar="FACES")
    ap.add_argument("--surfaces", nargs="+", default=list(SURFACES), choices=SURFACES)
    ap.add_argument("--quick", action="store_true", help="only the smallest size")
    ap.add_argument("--child", type=Path, metavar="MESH", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        return child(args.child)
    sizes = sorted(set(args.sizes))[:1] if args.quick else sorted(set(args.sizes))
    results: dict[tuple[str, int], dict] = {}
    failures = []
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        meshes = {name: write_meshes(name, sizes, Path(tmp)) for name in args.surfaces}
        for name in args.surfaces:
            for target, mesh in zip(sizes, meshes[name]):
                print(f"[{name} ~{target}] running ...", file=sys.stderr, flush=True)
                try:
                    results[name, target] = run_child(mesh)
                except RuntimeError as exc:
                    failures.append(f"{name} ~{target}: {exc}")
    print(f"load average (1, 5, 15 min) at the start: {', '.join(f'{x:.2f}' for x in load0)}")
    print(f"load average (1, 5, 15 min) at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())} "
          f"on {os.cpu_count()} cores (the machine is shared: read the times with it)")
    print(f"{'surface':<12} {'faces':>7} {'pred.faces':>10} {'predict s':>9} {'/ 10 s':>6} {'engine s':>8} "
          f"{'ratio':>6} {'iter':>5} {'start':>6} {'dev mean/p99/max %':>20} {'peak MB':>8}")
    for name in args.surfaces:
        for target in sizes:
            r = results.get((name, target))
            if r is None:
                print(f"{name:<12} {'~' + str(target):>7}  FAILED")
                continue
            dv = r["deviation"]
            print(f"{name:<12} {r['faces']:>7} {r['predict_faces']:>10} {r['predict_s']:>9.2f} "
                  f"{r['predict_s'] / GOAL_S:>6.2f} {r['engine_s']:>8.2f} {r['predict_s'] / r['engine_s']:>6.2f} {r['iterations']:>5} "
                  f"{r['start']:>6} {dv['mean']:>6.2f}/{dv['p99']:>5.2f}/{dv['max']:>5.2f} "
                  f"{r['peak_rss_kb'] / 1024:>8.0f}" + ("" if r["converged"] else "  NOT CONVERGED"))
    print("engine = the sum of report.timings_s (load, curvature, flatten, stripes, ribbons, gcode, preview); "
          "ratio = predict / engine (goal ≤ 1); / 10 s = predict / the 10 s goal (goal ≤ 1); iter = Newton "
          "iterations of all three solves; peak MB = the whole design with the prediction (own process)")
    print("\ngoals:")
    for (name, target), r in sorted(results.items()):
        ratio = r["predict_s"] / r["engine_s"]
        print(f"{name:<12} {r['faces']:>7} faces: prediction {r['predict_s']:.2f} s = "
              f"{r['predict_s'] / GOAL_S:.2f} × the goal (≤ {GOAL_S:.0f} s): "
              + ("met" if r["predict_s"] <= GOAL_S else "NOT met")
              + f"; ratio {ratio:.2f} (goal ≤ {GOAL_RATIO:.0f}): " + ("met" if ratio <= GOAL_RATIO else "NOT met")
              + (f"; peak {r['peak_rss_kb'] / 1024:.0f} MB (goal ≤ {GOAL_MB:.0f}): "
                 + ("met" if r["peak_rss_kb"] / 1024 <= GOAL_MB else "NOT met") if r["faces"] > 100_000 else ""))
    if failures:
        print("\n" + "\n\n".join(failures), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
