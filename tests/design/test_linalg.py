"""The sparse solves of the engine (``ribbond.design.linalg``) on both back ends: cholespy where it has
wheels, scipy's SuperLU where it has none (linux/aarch64). The same solutions, and the engine's tests
green with the optional native packages hidden (``--hide-package``, tests/conftest.py)."""

from __future__ import annotations

import functools
import importlib.util
import logging
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import igl
import numpy as np
import pytest
import scipy.sparse as sp

from ribbond.design import linalg, surfaces
from ribbond.design.linalg import SymmetricFactor
from ribbond.mesh.files import write_obj
from ribbond.design.params import DesignParameters
from ribbond.pipeline.compile import design_mesh
from ribbond.design.stripes import StripeSolver, integrable_frequency
from tests.test_wheels import absent_on

ROOT = Path(__file__).resolve().parents[2]
HAS_CHOLESPY = importlib.util.find_spec("cholespy") is not None

#: The engine's test modules whose solves go through ``SymmetricFactor`` (every call site: the
#: flattening's global step, Tutte start and row-count coupling; the stripes' inverse power iteration;
#: the stripes' integrable frequency, here in test_linalg.py).
SOLVER_TESTS = ("tests/design/test_flatten.py", "tests/design/test_stripes.py", "tests/design/test_linalg.py")


@functools.cache
def cotangent_laplacian() -> sp.csc_matrix:
    """The cotangent Laplacian of a saddle (positive semidefinite, the constants its kernel), its last
    vertex pinned: symmetric positive definite, as the flattening factorizes it (Eq. 9)."""
    V, F = surfaces.saddle(size=80.0, rings=16)
    L = -igl.cotmatrix(V, F.astype(np.int64))
    n = L.shape[0]
    return sp.csc_matrix(L[: n - 1, : n - 1])


@functools.cache
def condition_number() -> float:
    eigenvalues = np.linalg.eigvalsh(cotangent_laplacian().toarray())
    assert eigenvalues[0] > 0, "the pinned cotangent Laplacian must be positive definite"
    return float(eigenvalues[-1] / eigenvalues[0])


def test_the_pinned_cotangent_laplacian_is_symmetric_positive_definite() -> None:
    L = cotangent_laplacian()
    assert abs(L - L.T).max() < 1e-12
    assert condition_number() > 1.0


@pytest.mark.parametrize("columns", [None, 1, 3])
def test_scipy_solves_the_cotangent_laplacian(columns: int | None) -> None:
    """A manufactured solution comes back through the fallback: x = L⁻¹(L x)."""
    L = cotangent_laplacian()
    rng = np.random.default_rng(3)
    x = rng.standard_normal(L.shape[0] if columns is None else (L.shape[0], columns))
    solved = SymmetricFactor(L, backend="scipy").solve(L @ x)
    assert solved.shape == x.shape
    # a backward-stable solve: forward error within a small multiple of ε · cond(L)
    error = np.abs(solved - x).max() / np.abs(x).max()
    assert error <= 100 * np.finfo(float).eps * condition_number(), error


@pytest.mark.skipif(not HAS_CHOLESPY, reason="cholespy is not installed (no wheel for this machine)")
@pytest.mark.parametrize("columns", [None, 2])
def test_scipy_gives_the_cholespy_solution(columns: int | None) -> None:
    L = cotangent_laplacian()
    b = np.random.default_rng(5).standard_normal(L.shape[0] if columns is None else (L.shape[0], columns))
    reference = SymmetricFactor(L, backend="cholespy").solve(b)
    fallback = SymmetricFactor(L, backend="scipy").solve(b)
    assert np.abs(fallback - reference).max() <= 1e-10 * np.abs(reference).max()


def test_the_default_back_end_is_cholespy_where_installed_else_scipy() -> None:
    installed = importlib.util.find_spec("cholespy") is not None
    assert linalg.BACKEND == ("cholespy" if installed else "scipy")
    assert SymmetricFactor(sp.identity(3, format="csc")).backend == linalg.BACKEND


def test_the_back_end_in_use_is_logged_once(caplog: pytest.LogCaptureFixture,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(linalg, "_announced", False)
    with caplog.at_level(logging.INFO, logger="ribbond.design.linalg"):
        SymmetricFactor(sp.identity(2, format="csc"))
        SymmetricFactor(sp.identity(2, format="csc"))
    said = [r.getMessage() for r in caplog.records if r.name == "ribbond.design.linalg"]
    assert said == [f"sparse solver: {linalg.BACKEND_DESCRIPTION}"]
    assert linalg.BACKEND in said[0]


def test_the_stripes_integrable_frequency_solve() -> None:
    """The one solve no engine test reached (``stripes.integrable_frequency``), on the default back
    end: with X = (1, 0) on the unit square, ω = ν dx is closed exactly where ν does not vary with y
    (dω = -∂ν/∂y dx∧dy). Such a ν comes back unchanged; one varying with y is made closed (constant
    along each line x = const) when the spacing weight is small."""
    uv, F = surfaces.grid(12, 12)
    solver = StripeSolver(uv, F)
    X = np.tile([1.0, 0.0], (len(uv), 1))
    closed = 1.0 + 0.3 * uv[:, 0]
    assert np.abs(integrable_frequency(solver, X, closed, 1.0) - closed).max() <= 1e-10
    nu = integrable_frequency(solver, X, 1.0 + 0.3 * uv[:, 1], 1e-3)
    spread = [np.ptp(nu[np.isclose(uv[:, 0], x)]) for x in np.unique(uv[:, 0])]
    assert max(spread) <= 0.01 * 0.3


class _Stages:
    """Progress that keeps each stage's summary."""

    def __init__(self) -> None:
        self.summaries: dict[str, str] = {}

    def stage_started(self, stage: str, description: str) -> None:
        pass

    def iteration(self, stage: str, iteration: int, change: float, energy: float) -> None:
        pass

    def stage_finished(self, stage: str, seconds: float, summary: str) -> None:
        self.summaries[stage] = summary


def test_the_design_says_which_sparse_solver_it_used(tmp_path: Path) -> None:
    """The flatten stage's line (ribbonctl design's progress, the daemon's stage event) names it."""
    V, F = surfaces.cylinder_patch(40.0, 120.0, 60.0, n_around=16, n_along=8)
    write_obj(tmp_path / "cylinder.obj", V, F)
    stages = _Stages()
    design_mesh(tmp_path / "cylinder.obj", DesignParameters(), progress=stages, predict=False)
    expected = "cholespy (CHOLMOD" if importlib.util.find_spec("cholespy") else "scipy SuperLU"
    assert stages.summaries["flatten"].endswith(f"; sparse solver {linalg.BACKEND_DESCRIPTION}")
    assert expected in stages.summaries["flatten"]


def test_a_back_end_that_is_unknown_or_missing_is_named() -> None:
    with pytest.raises(ValueError, match="'umfpack'"):
        SymmetricFactor(sp.identity(2, format="csc"), backend="umfpack")
    if not HAS_CHOLESPY:
        with pytest.raises(ValueError, match="'cholespy' is not installed"):
            SymmetricFactor(sp.identity(2, format="csc"), backend="cholespy")
    with pytest.raises(ValueError, match="3 rows, the matrix 2"):
        SymmetricFactor(sp.identity(2, format="csc")).solve(np.ones(3))


def test_cholespy_is_optional_only_where_it_has_no_wheel() -> None:
    """pyproject.toml leaves cholespy out on linux/aarch64 and nothing else: the engine does without it."""
    assert absent_on("aarch64") == ["cholespy"]
    assert absent_on("x86_64") == []


@pytest.mark.skipif(not HAS_CHOLESPY, reason="cholespy is not installed: this run is already the fallback")
def test_engine_tests_pass_with_the_optional_native_packages_hidden() -> None:
    """The solver tests in a fresh interpreter with every package linux/aarch64 goes without hidden."""
    absent = absent_on("aarch64")
    own = f"{Path(__file__).relative_to(ROOT)}::{sys._getframe().f_code.co_name}"   # not itself again
    hide = [arg for name in absent for arg in ("--hide-package", name)]
    command = [sys.executable, "-m", "pytest", "-v", "-p", "no:cacheprovider", "-o", "addopts=", *hide,
               "--deselect", own, *SOLVER_TESTS]
    path = [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]
    started = time.perf_counter()
    run = subprocess.run(command, cwd=ROOT, env={**os.environ, "PYTHONPATH": os.pathsep.join(path)},
                         capture_output=True, text=True, timeout=240)
    output = run.stdout + run.stderr
    assert run.returncode == 0, output[-4000:]
    assert f"hidden packages (imports fail): {', '.join(absent)}" in output
    summary = output.strip().splitlines()[-1]
    assert re.search(r"\d+ passed", summary) and not re.search(r"failed|error", summary), summary
    # inside, the default back end was checked to be scipy, and the flattening and stripes ran on it
    assert "::test_the_default_back_end_is_cholespy_where_installed_else_scipy PASSED" in output
    assert "::test_the_design_says_which_sparse_solver_it_used PASSED" in output
    for module in ("test_flatten", "test_stripes"):
        assert re.search(rf"{module}\.py::\S+ PASSED", output), module
    print(f"fallback run: {summary} ({time.perf_counter() - started:.1f} s)")
