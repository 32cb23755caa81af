"""The layout optimized against the prediction (issue 34): its gradients against finite differences,
and what an optimization must do (lower its objective, keep τ in the table's range, repeat itself).

The sheet: a 60 × 40 mm rectangle under a staggered pattern (§3) of random thicknesses, the target a
cylinder of radius 45 mm over the contracted sheet (a shape the pattern can approach, not reach)."""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.deploy.optimize import Objective, layout_model, optimize_layout, table_slope
from ribbond.deploy.predict import RELEASES, predict_deployed
from ribbond.deploy.release import release
from ribbond.design import surfaces
from ribbond.design.thickness import load_curvature_table, table_curvature

from .patterns import staggered_pattern

TABLE = load_curvature_table("tpu95a-lycra-default")
S, W = 1.6, 1.5


@pytest.fixture(scope="module")
def sheet():
    UV, F = surfaces.grid(14, 10)
    uv = UV * np.array([60.0, 40.0])
    rng = np.random.default_rng(0)
    ribbons = staggered_pattern((60.0, 40.0), 12.0, 6.0, 9.0, 0.5)
    ribbons = [r.model_copy(update={"thickness": float(t)})
               for r, t in zip(ribbons, rng.uniform(0.45, 0.75, len(ribbons)))]
    radius, c = 45.0, uv / S
    angle = (c[:, 0] - c[:, 0].mean()) / radius
    target = np.column_stack([radius * np.sin(angle), c[:, 1], radius * (1 - np.cos(angle))])
    return uv, F, target, ribbons


def test_table_slope_is_the_derivative_of_the_interpolation():
    rng = np.random.default_rng(1)
    tau = rng.uniform(0.25, 1.55, 50)
    mu2 = rng.uniform(3.5, 15.0, 50)
    h = 1e-6
    for side in ("front", "back"):
        fd = (table_curvature(TABLE, side, tau + h, mu2) - table_curvature(TABLE, side, tau - h, mu2)) / (2 * h)
        np.testing.assert_allclose(table_slope(TABLE, side, tau, mu2), fd, rtol=1e-6)


def test_layout_model_reproduces_the_coverage_curvature_and_thickness(sheet):
    """κ_f and τ_f recomputed from the ribbon weights are those the coverage measured."""
    from ribbond.deploy.rest_forms import face_coverage
    uv, F, target, ribbons = sheet
    model = layout_model(uv, F, target, ribbons, prestretch=S, ribbon_width=W, table=TABLE)
    cov = face_coverage(uv, F, ribbons, W, TABLE)
    kappa_f, tau_f, _, _ = model.face_values(np.array([r.thickness for r in ribbons]))
    np.testing.assert_allclose(kappa_f, cov.kappa, atol=1e-12)
    np.testing.assert_allclose(tau_f, cov.thickness, atol=1e-12)


def test_adjoint_gradient_matches_finite_differences(sheet):
    """dJ/dτ_r by the adjoint against central differences of J (each from the same equilibrium start,
    Newton converged to rounding: the soft modes make a loosely converged J useless for differences)."""
    uv, F, target, ribbons = sheet
    model = layout_model(uv, F, target, ribbons, prestretch=S, ribbon_width=W, table=TABLE)
    tau = np.array([r.thickness for r in ribbons])
    obj = Objective(model, release(model.base).X)
    _, grad = obj(tau)
    start, h = obj.X.copy(), 1e-4
    for r in np.argsort(-np.abs(grad))[:4]:
        values = []
        for sign in (1.0, -1.0):
            t = tau.copy()
            t[r] += sign * h
            values.append(Objective(model, start)(t)[0])
        assert grad[r] == pytest.approx((values[0] - values[1]) / (2 * h), rel=1e-3)


def test_optimization_lowers_the_objective_within_bounds_and_repeats_itself(sheet):
    uv, F, target, ribbons = sheet
    kw = dict(prestretch=S, ribbon_width=W, table=TABLE)
    forward = predict_deployed(uv, target, F, ribbons, releases=RELEASES[:1], **kw)
    runs = [optimize_layout(uv, target, F, ribbons, forward, faces=300, max_evaluations=15, budget_s=600, **kw)
            for _ in range(2)]
    opt = runs[0]
    assert opt.objective < 0.9 * opt.objective_forward
    assert opt.evaluations <= 15
    assert np.all(opt.thickness >= TABLE.thickness[0]) and np.all(opt.thickness <= TABLE.thickness[-1])
    assert [r.thickness for r in opt.ribbons] == list(opt.thickness)
    assert all(a.points == b.points and a.side == b.side for a, b in zip(opt.ribbons, ribbons))
    np.testing.assert_array_equal(runs[1].thickness, opt.thickness)


def test_optimization_stops_at_its_budget(sheet):
    uv, F, target, ribbons = sheet
    kw = dict(prestretch=S, ribbon_width=W, table=TABLE)
    forward = predict_deployed(uv, target, F, ribbons, releases=RELEASES[:1], **kw)
    opt = optimize_layout(uv, target, F, ribbons, forward, faces=300, budget_s=1e-3, **kw)
    assert opt.stopped == "time budget" and opt.evaluations == 1
    with pytest.raises(ValueError, match="budget_s"):
        optimize_layout(uv, target, F, ribbons, forward, budget_s=0.0, **kw)


def test_forward_design_has_no_optimization(tmp_path):
    """``optimize=False`` (``--no-optimize``) and ``[solver] optimize = false``: the paper's forward design,
    each ribbon's thickness the table's inverse at its κ1 and μ2, no report.optimization."""
    from ribbond.mesh.files import write_obj
    from ribbond.design.params import DesignParameters, SizeSpec, SolverSettings
    from ribbond.pipeline.compile import design_mesh
    from ribbond.design.thickness import ribbon_thickness
    V, F = surfaces.cylinder_patch()
    path = tmp_path / "cylinder.obj"
    write_obj(path, V, F)
    params = DesignParameters(size=SizeSpec(bbox_diagonal=100.0))
    for solver, optimize in ((SolverSettings(refine_below_faces=0), False),
                             (SolverSettings(refine_below_faces=0, optimize=False), True)):
        res = design_mesh(path, params, solver, optimize=optimize)
        assert res.design.report.optimization is None and res.design.report.deployed is not None
        assert "optimize" not in res.design.report.timings_s
        rib = res.design.ribbons
        tau = ribbon_thickness(TABLE, np.array([r.kappa1 for r in rib]), np.array([r.spacing[1] for r in rib]))
        np.testing.assert_allclose([r.thickness for r in rib], tau.thickness)


def test_the_daemon_passes_its_design_switches_to_the_compile_worker():
    from ribbond.daemon.components.compiler import COMPILE_STAGES, worker_command
    from ribbond.pipeline.compile import STAGES
    assert [s.name for s in STAGES] == [s for s in COMPILE_STAGES if s != "write"]
    cmd = worker_command("py", "m.obj", "out", {}, "plans")
    assert "--no-optimize" not in cmd and "--no-predict" not in cmd
    assert worker_command("py", "m.obj", "out", {}, "plans", optimize=False)[-1] == "--no-optimize"


def test_the_command_lines_take_the_optimization_as_asked():
    from ribbond.client.cli import build_parser
    parser = build_parser()
    assert parser.parse_args(["design", "m.obj", "-o", "out"]).optimize                # on by default
    assert not parser.parse_args(["design", "m.obj", "-o", "out", "--no-optimize"]).optimize
    assert parser.parse_args(["submit", "m.obj", "--no-optimize"]).no_optimize
    with pytest.raises(SystemExit):
        parser.parse_args(["predict", "folder", "--fine"])          # the ribbon-resolved model is gone


def _prediction(mean: float, worst: float, reached: bool):
    """A stand-in with the three figures ``optimization_kept`` reads (a Prediction's own names)."""
    from types import SimpleNamespace
    return SimpleNamespace(deviation_pct={"mean": mean}, agreement=SimpleNamespace(spread_mean=(mean, worst)),
                           reached=reached)


@pytest.mark.parametrize("forward, optimized, kept, words", [
    ((2.0, 2.5, False), (1.2, 1.4, False), True, "2.00 → 1.20"),
    ((2.0, 2.5, False), (2.0, 2.2, False), False, "not below"),            # no better on the mean
    ((2.0, 2.5, False), (1.2, 8.0, False), False, "worst release 8.00"),   # another branch on one release
    ((1.0, 1.1, True), (0.9, 1.0, False), False, "reached"),               # keeps ``reached``
])
def test_the_optimized_layout_is_kept_only_where_its_own_prediction_is_better(forward, optimized, kept, words):
    from ribbond.pipeline.compile import optimization_kept
    ok, why = optimization_kept(_prediction(*forward), _prediction(*optimized))
    assert ok is kept and words in why
