"""Intake of the target surface: cleaning, and one test per reason to refuse a mesh.

Expectations come from the constructions: a (k × k)-cell grid is a disk with (k+1)² vertices,
2k² faces and a boundary of 4k vertices; a torus grid is closed with Euler characteristic 0, etc.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from ribbond.design.errors import MeshError
from ribbond.design.intake import CleanedMesh, TargetMesh, check_disk, clean_mesh, load_target
from ribbond.mesh.files import write_obj
from tests.design.test_mesh_io import grid, write_stl_binary


def periodic_grid(a: int, b: int, *, wrap_rows: bool) -> tuple[np.ndarray, np.ndarray]:
    """A grid of a × b cells wrapped in its columns (a cylinder) and optionally its rows (a torus).

    Vertices (i, j) on a torus of radii 2 and 1 (j around the tube's axis, i around the tube);
    faces consistently oriented.
    """
    rows = a if wrap_rows else a + 1
    i, j = np.meshgrid(np.arange(rows), np.arange(b), indexing="ij")
    u = 2 * np.pi * j.ravel() / b
    v = 2 * np.pi * i.ravel() / a if wrap_rows else i.ravel() / a
    if wrap_rows:
        V = np.column_stack([(2 + np.cos(v)) * np.cos(u), (2 + np.cos(v)) * np.sin(u), np.sin(v)])
    else:
        V = np.column_stack([np.cos(u), np.sin(u), v])
    ii, jj = np.meshgrid(np.arange(a), np.arange(b), indexing="ij")
    p00 = (ii * b + jj) % (rows * b)
    p01 = (ii * b + (jj + 1) % b) % (rows * b)
    p10 = ((ii + 1) * b + jj) % (rows * b)
    p11 = ((ii + 1) * b + (jj + 1) % b) % (rows * b)
    F = np.concatenate([np.column_stack([p00.ravel(), p01.ravel(), p11.ravel()]),
                        np.column_stack([p00.ravel(), p11.ravel(), p10.ravel()])])
    return V.astype(np.float64), F.astype(np.int64)


def octahedron() -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-oriented octahedron: 6 vertices, 8 faces."""
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = []
    for sx, x in ((1, 0), (-1, 1)):
        for sy, y in ((1, 2), (-1, 3)):
            for sz, z in ((1, 4), (-1, 5)):
                faces.append((x, y, z) if sx * sy * sz > 0 else (x, z, y))
    return V, np.array(faces, dtype=np.int64)


def refusal(V: np.ndarray, F: np.ndarray) -> MeshError:
    with pytest.raises(MeshError) as exc:
        check_disk(V, F)
    return exc.value


# ---------------------------------------------------------------------------------------------
# Cleaning
# ---------------------------------------------------------------------------------------------


def test_clean_mesh_merges_a_triangle_soup() -> None:
    V, F, _ = grid(4)
    soup_V = V[F].reshape(-1, 3)
    soup_F = np.arange(96).reshape(32, 3)
    cleaned = clean_mesh(soup_V, soup_F)
    assert isinstance(cleaned, CleanedMesh)
    assert cleaned.V.shape == (25, 3) and cleaned.F.shape == (32, 3)
    assert cleaned.merged == 96 - 25 and cleaned.unreferenced == 0
    np.testing.assert_array_equal(cleaned.V[cleaned.F], V[F])  # faces and corners in order


def test_clean_mesh_merges_within_tolerance_only() -> None:
    V, F, _ = grid(1)  # diagonal √(1 + 1 + 0.125²)
    # Split the shared edge (0–3): the second face gets its own copies 4 and 5.
    V2 = np.vstack([V, V[0] + [1e-9, 0, 0], V[3] + [0, -1e-9, 0]])
    F2 = np.array([[0, 1, 3], [4, 5, 2]])
    near = clean_mesh(V2, F2)
    assert near.merged == 2 and near.unreferenced == 0
    np.testing.assert_array_equal(near.F, F)
    np.testing.assert_array_equal(near.V, V)
    far = clean_mesh(V2 + np.vstack([np.zeros((4, 3)), [[1e-3, 0, 0]] * 2]), F2)
    assert far.merged == 0 and len(far.V) == 6
    exact_only = clean_mesh(V2, F2, merge_tolerance=0.0)
    assert exact_only.merged == 0


def test_clean_mesh_drops_unreferenced_vertices_and_keeps_order() -> None:
    V, F, _ = grid(2)
    extra = np.vstack([[[5.0, 5.0, 5.0]], V, [[7.0, 7.0, 7.0]]])  # one unused vertex at each end
    cleaned = clean_mesh(extra, F + 1)
    assert cleaned.unreferenced == 2 and cleaned.merged == 0
    np.testing.assert_array_equal(cleaned.V, V)
    np.testing.assert_array_equal(cleaned.F, F)


def test_clean_mesh_leaves_non_finite_vertices_for_the_check() -> None:
    V, F, _ = grid(2)
    V = V.copy()
    V[4] = np.nan
    cleaned = clean_mesh(V, F)
    assert cleaned.merged == 0 and len(cleaned.V) == 9
    assert refusal(cleaned.V, cleaned.F).problem == "non_finite"


def test_clean_mesh_rejects_bad_indices() -> None:
    V, F, _ = grid(1)
    with pytest.raises(MeshError) as exc:
        clean_mesh(V, F + 10)
    assert exc.value.problem == "bad_index"


# ---------------------------------------------------------------------------------------------
# The disk check
# ---------------------------------------------------------------------------------------------


def test_grid_is_a_disk_and_its_boundary_is_the_border() -> None:
    k = 4
    V, F, _ = grid(k)
    loop = check_disk(V, F)
    assert loop.dtype == np.int64 and len(loop) == 4 * k
    i, j = np.divmod(loop, k + 1)
    assert set(loop.tolist()) == {int(v) for v in range(25) if v // 5 in (0, 4) or v % 5 in (0, 4)}
    steps = np.abs(np.diff(np.r_[i, i[0]])) + np.abs(np.diff(np.r_[j, j[0]]))
    assert np.all(steps == 1)  # consecutive loop vertices are grid neighbours along the border


def test_empty() -> None:
    assert refusal(np.zeros((3, 3)), np.zeros((0, 3), dtype=int)).problem == "empty"


def test_non_finite() -> None:
    V, F, _ = grid(2)
    V = V.copy()
    V[7, 1] = np.inf
    err = refusal(V, F)
    assert err.problem == "non_finite" and "vertex 7" in str(err)


def test_bad_index_out_of_range_and_repeated_vertex() -> None:
    V, F, _ = grid(2)
    F = F.copy()
    F[3, 2] = 99
    err = refusal(V, F)
    assert err.problem == "bad_index" and "face 3" in str(err) and "99" in str(err)
    F[3, 2] = F[3, 0]
    err = refusal(V, F)
    assert err.problem == "bad_index" and "face 3" in str(err) and "repeats" in str(err)


def test_zero_area() -> None:
    V, F, _ = grid(1)  # faces (0, 1, 3) and (0, 3, 2)
    V = V.copy()
    V[1] = (V[0] + V[3]) / 2  # face 0 collapses onto the diagonal; face 1 keeps its area
    err = refusal(V, F)
    assert err.problem == "zero_area" and "face 0" in str(err) and "face 1" not in str(err)
    centroid = (V[0] + V[1] + V[3]) / 3
    assert f"{centroid[0]:.6g}" in str(err)


def test_non_manifold_edge() -> None:
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], float)
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # three faces on edge 0–1
    err = refusal(V, F)
    assert err.problem == "non_manifold_edge"
    assert "edge 0–1" in str(err) and "faces 0, 1, 2" in str(err)


def test_orientation() -> None:
    V, F, _ = grid(3)
    F = F.copy()
    F[5] = F[5, ::-1]
    err = refusal(V, F)
    assert err.problem == "orientation" and "face" in str(err) and "winding" in str(err)
    assert "5" in str(err)


def test_orientation_names_the_faces_to_reverse() -> None:
    V, F, _ = grid(3)  # 18 faces; reverse the bottom row's 6
    F = F.copy()
    F[:6] = F[:6, ::-1]
    err = refusal(V, F)
    assert err.problem == "orientation" and "reversing 6 faces (0, 1, 2, 3, 4 and 1 more)" in str(err)


def test_orientation_of_a_moebius_strip() -> None:
    n = 12
    t = np.arange(n) * 2 * np.pi / n

    def ring(w: float) -> np.ndarray:  # the strip's edge at offset w across it, half a twist
        return np.column_stack([(1 + w * np.cos(t / 2)) * np.cos(t),
                                (1 + w * np.cos(t / 2)) * np.sin(t), w * np.sin(t / 2)])

    V = np.vstack([ring(-0.3), ring(0.3)])  # vertex i on one side, n + i on the other
    i = np.arange(n - 1)
    quads = np.column_stack([i, i + 1, n + i + 1, n + i])
    quads = np.vstack([quads, [n - 1, n, 0, 2 * n - 1]])  # the twisted join swaps the sides
    F = np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    err = refusal(V, F)
    assert err.problem == "orientation" and "not orientable" in str(err)


def test_non_manifold_vertex_bow_tie() -> None:
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0]], float)
    F = np.array([[0, 1, 2], [0, 3, 4]])  # two triangles touching at vertex 0
    err = refusal(V, F)
    assert err.problem == "non_manifold_vertex" and "vertex 0" in str(err) and "2 fans" in str(err)


def test_non_manifold_vertex_two_disks_at_a_corner() -> None:
    V, F, _ = grid(2)  # 9 vertices; corner 8 is (1, 1)
    V2 = np.vstack([V, V[1:] + [1.0, 1.0, 0.125]])  # a second grid whose corner 0 is vertex 8
    remap = np.r_[8, np.arange(9, 17)]
    F2 = np.vstack([F, remap[F]])
    err = refusal(V2, F2)
    assert err.problem == "non_manifold_vertex" and "vertex 8" in str(err)


def test_components() -> None:
    V, F, _ = grid(2)
    V1, F1, _ = grid(1)
    V2 = np.vstack([V, V1 + [5.0, 0.0, 0.0]])
    F2 = np.vstack([F, F1 + len(V)])
    err = refusal(V2, F2)
    assert err.problem == "components"
    assert "2 separate" in str(err) and "8, 2" in str(err)


def test_closed() -> None:
    V, F = octahedron()
    err = refusal(V, F)
    assert err.problem == "closed" and "cut" in str(err)
    V, F = periodic_grid(6, 8, wrap_rows=True)  # torus
    assert refusal(V, F).problem == "closed"


def test_not_disk_cylinder_has_two_boundary_loops() -> None:
    V, F = periodic_grid(3, 8, wrap_rows=False)
    err = refusal(V, F)
    assert err.problem == "not_disk"
    assert "2 boundary loops" in str(err) and "genus 0" in str(err) and "cuts" in str(err)


def test_not_disk_annulus_from_a_grid_with_a_hole() -> None:
    V, F, _ = grid(4)
    keep = np.ones(len(F), dtype=bool)
    keep[[2 * (4 + 1), 2 * (4 + 1) + 1, 2 * (4 + 2), 2 * (4 + 2) + 1,
          2 * (8 + 1), 2 * (8 + 1) + 1, 2 * (8 + 2), 2 * (8 + 2) + 1]] = False  # the central 2×2 cells
    err = refusal(V, F[keep])
    assert err.problem == "not_disk" and "2 boundary loops" in str(err) and "1 hole" in str(err)


def test_not_disk_punctured_torus_has_genus_one() -> None:
    V, F = periodic_grid(6, 8, wrap_rows=True)
    err = refusal(V, F[1:])  # one face removed: one boundary loop, Euler characteristic −1
    assert err.problem == "not_disk" and "1 boundary loop " in str(err) and "genus 1" in str(err)


# ---------------------------------------------------------------------------------------------
# load_target
# ---------------------------------------------------------------------------------------------


def test_load_target_from_binary_stl(tmp_path: Path) -> None:
    V, F, _ = grid(4)
    path = tmp_path / "target.stl"
    write_stl_binary(path, V, F)
    target = load_target(path, max_faces=1000)
    assert isinstance(target, TargetMesh)
    assert target.V.shape == (25, 3) and target.F.shape == (32, 3)
    assert target.source_faces == 32 and target.merged == 96 - 25 and target.unreferenced == 0
    assert target.name == "target.stl"
    assert target.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    assert len(target.boundary) == 16
    np.testing.assert_allclose(target.V[target.F], V[F], atol=1e-6)


def test_load_target_messages_start_with_the_file_name(tmp_path: Path) -> None:
    V, F = octahedron()
    write_obj(tmp_path / "ball.obj", V, F)
    with pytest.raises(MeshError) as exc:
        load_target(tmp_path / "ball.obj", max_faces=100)
    assert exc.value.problem == "closed" and str(exc.value).startswith("ball.obj: ")
    with pytest.raises(MeshError) as exc:
        load_target(tmp_path / "ball.obj", max_faces=7)
    assert exc.value.problem == "too_many_faces"


def test_load_target_reports_non_finite_with_file_indices(tmp_path: Path) -> None:
    """Issue 36 item 12: a NaN on an OBJ's 5th 'v' line is vertex 5 on that line, as the file's
    faces number it (from 1) and as face errors name their line; a comment line before it moves
    the line, not the number. OFF numbers its vertices from 0 and has no line per vertex."""
    V, F, _ = grid(2)
    vertices = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist()).replace("v 0.5 0.5", "v nan 0.5", 1)
    faces = "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F.tolist())
    assert vertices.splitlines()[4].startswith("v nan")                    # (0.5, 0.5) is the 5th
    for header, line in (("", 5), ("# a comment\n\n", 7)):
        (tmp_path / "nan.obj").write_text(header + vertices + faces)
        with pytest.raises(MeshError) as exc:
            load_target(tmp_path / "nan.obj", max_faces=100)
        assert exc.value.problem == "non_finite" and f"vertex 5 on line {line} at (nan, 0.5" in str(exc.value), \
            str(exc.value)
    bad = V.copy()
    bad[4, 0] = np.nan
    (tmp_path / "nan.off").write_text(f"OFF\n{len(bad)} {len(F)} 0\n"
                                      + "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in bad.tolist())
                                      + "".join(f"3 {a} {b} {c}\n" for a, b, c in F.tolist()))
    with pytest.raises(MeshError) as exc:
        load_target(tmp_path / "nan.off", max_faces=100)
    assert "vertex 4 at (nan, 0.5" in str(exc.value) and "line" not in str(exc.value), str(exc.value)


def test_check_disk_is_fast_on_a_big_grid() -> None:
    import time

    V, F, _ = grid(150)  # 45 000 faces
    start = time.perf_counter()
    loop = check_disk(V, F)
    assert len(loop) == 600
    assert time.perf_counter() - start < 2.0  # vectorized: ≈ 0.1 s


def test_one_triangle_is_too_small() -> None:
    """Issue 22 item 10: a single triangle has no interior edge (the deployed shape's bending lives
    there): refused at intake, not at the deploy stage. Two triangles sharing an edge pass."""
    V = np.array([[0.0, 0.0, 0.0], [40.0, 0.0, 0.0], [0.0, 40.0, 5.0], [40.0, 40.0, 0.0]])
    err = refusal(V[:3], np.array([[0, 1, 2]]))
    assert err.problem == "too_small"
    assert "1 face" in str(err) and "at least 2 faces" in str(err)
    loop = check_disk(V, np.array([[0, 1, 2], [1, 3, 2]]))
    assert sorted(loop.tolist()) == [0, 1, 2, 3]


def test_ribbonctl_design_refuses_one_triangle_before_any_stage(tmp_path: Path) -> None:
    import subprocess
    import sys

    mesh = tmp_path / "one.obj"
    mesh.write_text("v 0 0 0\nv 40 0 0\nv 0 40 5\nf 1 2 3\n")
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "design", str(mesh), "-o", str(tmp_path / "d"), "-q"],
                          cwd=root, text=True, capture_output=True, timeout=300)
    assert proc.returncode == 2, proc.stderr                 # bad input, not "cannot make this design"
    assert "at least 2 faces" in proc.stderr and "F must have shape" not in proc.stderr, proc.stderr
    assert not (tmp_path / "d").exists()
