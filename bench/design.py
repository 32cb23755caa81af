"""Benchmark of the whole design engine on meshes of about 10k, 40k and 160k faces.

For each surface (the torus patch of the paper's Fig. 2 and the saddle disk of
``examples/meshes``) and each size, one fresh subprocess runs ``design_mesh`` as ``ribbonctl
design`` does (default parameters and solver settings, size left to the printer's frame) and
reports the per-stage times (load, curvature, flatten, stripes, ribbons, preview) and its own peak
resident memory, so the memory of a run is that run's alone. Then how each stage's time grows with
the mesh (exponent of faces: 1 is linear).

"Whole engine" = load + curvature + flatten + stripes + ribbons; the preview (rendering the SVG and
PNG) is shown apart and left out. Goals (at 160k faces): the whole engine within 2× the flattening
alone, the curvature stage (principal curvatures and the k1 line field) within 0.5× the flattening,
and under 2 GB of memory.

    python bench/design.py [--quick] [--sizes 10000 40000 160000] [--surfaces torus_patch saddle]
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "examples" / "meshes"))

STAGES = ("load", "curvature", "flatten", "stripes", "ribbons")  # the whole engine
SIZES = (10_000, 40_000, 160_000)
SURFACES = ("torus_patch", "saddle")
GOAL_RATIO = 2.0
GOAL_FRONT_END = 0.5     # curvature + line field against the flattening, at the largest size
GOAL_MB = 2048.0
RESULT_TAG = "BENCH-RESULT "


# -- child: one run of the engine in its own process ------------------------------------------------

def child(mesh: Path) -> int:
    """Run the engine on ``mesh`` and print one JSON line (tagged) with the times and peak memory."""
    from ribbond.design.params import DesignParameters, SolverSettings
    from ribbond.pipeline.compile import design_mesh

    t = time.perf_counter()
    result = design_mesh(mesh, DesignParameters(), SolverSettings(), predict=False)
    wall = time.perf_counter() - t
    rep = result.design.report
    out = {
        "faces": rep.faces,
        "timings": dict(rep.timings_s),
        "time_s": rep.time_s,
        "wall_s": wall,
        "ribbons": len(result.design.ribbons),
        "iterations": result.flattening.iterations,
        "converged": bool(result.flattening.converged),
        "stripe_faces": int(len(result.stripes.F)),
        "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,  # kB on Linux
    }
    print(RESULT_TAG + json.dumps(out), flush=True)
    return 0


# -- parent -----------------------------------------------------------------------------------------

def write_meshes(surface: str, targets: list[int], workdir: Path) -> list[Path]:
    """The surface at resolutions giving about ``targets`` faces; the OBJ paths."""
    from make_meshes import examples

    from ribbond.mesh.files import write_obj

    file = f"{surface}.obj"
    _, F1 = examples(1.0)[file][1]()
    paths = []
    for target in targets:
        scale = math.sqrt(target / len(F1))
        V, F = examples(scale)[file][1]()
        path = workdir / f"{surface}_{target}.obj"
        write_obj(path, V, F, header=f"bench: {surface}, scale {scale:.4f}")
        print(f"mesh {surface:<12} target {target:>7} faces: scale {scale:6.3f} -> {len(F):>7} faces, "
              f"{len(V):>7} vertices", flush=True)
        paths.append(path)
    return paths


def run_child(mesh: Path, script: Path | None = None) -> dict:
    """Run ``script`` (default this one) with ``--child MESH`` in a fresh subprocess and return its
    tagged JSON line; raise RuntimeError if it fails."""
    script = script or Path(__file__)
    proc = subprocess.run([sys.executable, str(script.resolve()), "--child", str(mesh)],
                          capture_output=True, text=True, cwd=ROOT)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_TAG)]
    if proc.returncode != 0 or not lines:
        tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-25:])
        raise RuntimeError(f"the run on {mesh.name} failed (exit code {proc.returncode}):\n{tail}")
    return json.loads(lines[-1][len(RESULT_TAG):])


def engine_s(r: dict) -> float:
    return sum(r["timings"][s] for s in STAGES)


def growth(t0: float, t1: float, f0: int, f1: int) -> float:
    """Exponent p of t ∝ faces^p between two runs."""
    if t0 <= 0 or t1 <= 0 or f0 == f1:
        return float("nan")
    return math.log(t1 / t0) / math.log(f1 / f0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), metavar="FACES",
                    help=f"target face counts (default {' '.join(map(str, SIZES))})")
    ap.add_argument("--surfaces", nargs="+", default=list(SURFACES), choices=SURFACES,
                    help=f"surfaces (default {' '.join(SURFACES)})")
    ap.add_argument("--quick", action="store_true", help="only the smallest size (a smoke run)")
    ap.add_argument("--child", type=Path, metavar="MESH", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        return child(args.child)
    if any(s <= 0 for s in args.sizes):
        ap.error("--sizes: face counts must be positive")
    sizes = sorted(set(args.sizes))
    if args.quick:
        sizes = sizes[:1]

    results: dict[tuple[str, int], dict] = {}
    failures: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        print("writing meshes", file=sys.stderr, flush=True)
        meshes = {name: write_meshes(name, sizes, Path(tmp)) for name in args.surfaces}
        print(flush=True)
        for name in args.surfaces:
            for target, mesh in zip(sizes, meshes[name]):
                print(f"[{name} ~{target}] running ...", file=sys.stderr, flush=True)
                t = time.perf_counter()
                try:
                    r = run_child(mesh)
                except RuntimeError as exc:
                    print(f"[{name} ~{target}] FAILED after {time.perf_counter() - t:.1f} s",
                          file=sys.stderr, flush=True)
                    failures.append(f"{name} ~{target}: {exc}")
                    continue
                results[name, target] = r
                print(f"[{name} ~{target}] done in {time.perf_counter() - t:.1f} s: {r['faces']} faces, "
                      f"engine {engine_s(r):.2f} s, peak {r['peak_rss_kb'] / 1024:.0f} MB",
                      file=sys.stderr, flush=True)

    stage_cols = "".join(f" {s:>9}" for s in STAGES)
    print(f"{'surface':<12} {'faces':>7}{stage_cols} {'engine':>7} {'flatten':>7} {'ratio':>6} "
          f"{'preview':>7} {'peak MB':>7} {'ribbons':>7} {'iter':>5}")
    for name in args.surfaces:
        for target in sizes:
            r = results.get((name, target))
            if r is None:
                print(f"{name:<12} {'~' + str(target):>7}  FAILED")
                continue
            tm = r["timings"]
            print(f"{name:<12} {r['faces']:>7}" + "".join(f" {tm[s]:>9.2f}" for s in STAGES)
                  + f" {engine_s(r):>7.2f} {tm['flatten']:>7.2f} {engine_s(r) / tm['flatten']:>6.2f} "
                  f"{tm['preview']:>7.2f} {r['peak_rss_kb'] / 1024:>7.0f} {r['ribbons']:>7} "
                  f"{r['iterations']:>5}" + ("" if r["converged"] else "  NOT CONVERGED")
                  + (f"  (stripes on {r['stripe_faces']} faces)" if r["stripe_faces"] != r["faces"] else ""))
    print("times in s; engine = " + " + ".join(STAGES) + " (the preview rendering is shown apart and "
          "not counted); ratio = engine / flatten; peak MB = the run's peak resident memory (own "
          "process); iter = flattening iterations")

    if len(sizes) > 1:
        lo, hi = sizes[0], sizes[-1]
        print(f"\ngrowth of the time with the faces, ~{lo} -> ~{hi} (exponent p of t ∝ faces^p; "
              "1 = linear)")
        print(f"{'surface':<12}" + "".join(f" {s:>9}" for s in (*STAGES, "engine", "preview")))
        for name in args.surfaces:
            a, b = results.get((name, lo)), results.get((name, hi))
            if a is None or b is None:
                print(f"{name:<12}  (a run failed)")
                continue
            ta = {**a["timings"], "engine": engine_s(a)}
            tb = {**b["timings"], "engine": engine_s(b)}
            print(f"{name:<12}" + "".join(
                f" {growth(ta[s], tb[s], a['faces'], b['faces']):>9.2f}"
                for s in (*STAGES, "engine", "preview")))

    print(f"\ngoals at ~{sizes[-1]} faces (engine = {' + '.join(STAGES)}, preview excluded):")
    for name in args.surfaces:
        r = results.get((name, sizes[-1]))
        if r is None:
            print(f"{name:<12} (the run failed)")
            continue
        ratio = engine_s(r) / r["timings"]["flatten"]
        front = r["timings"]["curvature"] / r["timings"]["flatten"]
        mb = r["peak_rss_kb"] / 1024
        print(f"{name:<12} {r['faces']} faces: ratio engine / flatten = {ratio:.2f} (goal ≤ {GOAL_RATIO:.2f}): "
              + ("met" if ratio <= GOAL_RATIO else "NOT met"))
        print(f"{name:<12} {r['faces']} faces: ratio curvature + line field / flatten = {front:.2f} "
              f"(goal ≤ {GOAL_FRONT_END:.2f}): " + ("met" if front <= GOAL_FRONT_END else "NOT met"))
        print(f"{name:<12} {r['faces']} faces: peak memory = {mb:.0f} MB (goal < {GOAL_MB:.0f} MB): "
              + ("met" if mb < GOAL_MB else "NOT met"))

    if failures:
        print("\n" + "\n\n".join(failures), file=sys.stderr)
        print(f"\n{len(failures)} run(s) failed", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
