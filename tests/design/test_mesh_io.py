"""Reading and writing meshes: every format round-trips, malformed files raise MeshError only.

Meshes are built with numpy (a (k × k)-cell grid: (k+1)² vertices, 2k² triangles) and written by
the small writers below, independent of the code under test.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
import pytest

from ribbond.design.errors import MeshError
from ribbond.design.intake import clean_mesh
from ribbond.mesh import files as mesh_io
from ribbond.mesh.files import read_mesh, write_obj

# ---------------------------------------------------------------------------------------------
# Meshes and independent writers (also used by test_intake)
# ---------------------------------------------------------------------------------------------


def grid(k: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A gently curved (k × k)-cell grid disk.

    Returns V ((k+1)², 3), F (2k², 3) and the quads Q (k², 4) = (a, b, d, c) whose fans are F:
    F[2q] = (a, b, d), F[2q + 1] = (a, d, c), all counter-clockwise seen from +z.
    """
    j, i = np.meshgrid(np.arange(k + 1), np.arange(k + 1))
    x, y = j.ravel() / k, i.ravel() / k
    V = np.column_stack([x, y, 0.25 * x * x - 0.125 * y]).astype(np.float64)
    ii, jj = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    a = (ii * (k + 1) + jj).ravel()
    b, c = a + 1, a + k + 1
    d = c + 1
    Q = np.column_stack([a, b, d, c]).astype(np.int64)
    F = np.empty((2 * k * k, 3), dtype=np.int64)
    F[0::2] = np.column_stack([a, b, d])
    F[1::2] = np.column_stack([a, d, c])
    return V, F, Q


def write_off(path: Path, V: np.ndarray, polys: np.ndarray | list, *, colours: bool = False,
              header_line: bool = False) -> None:
    lines = ["OFF", "# a comment", ""]
    counts = f"{len(V)} {len(polys)} 0"
    if header_line:
        lines = [f"OFF {counts}", "# a comment"]
    else:
        lines.append(counts)
    lines += [" ".join(repr(float(c)) for c in v) for v in V]
    for p in polys:
        tail = " 255 0 0" if colours else ""
        lines.append(f"{len(p)} " + " ".join(str(int(i)) for i in p) + tail)
    path.write_text("\n".join(lines) + "\n")


def write_stl_ascii(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    out = ["solid grid"]
    for f in F:
        out += ["  facet normal 0 0 1", "    outer loop"]
        out += ["      vertex " + " ".join(map(repr, V[i].tolist())) for i in f]
        out += ["    endloop", "  endfacet"]
    out.append("endsolid grid")
    path.write_text("\n".join(out) + "\n")


STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def write_stl_binary(path: Path, V: np.ndarray, F: np.ndarray, *, header: bytes = b"binary grid",
                     count: int | None = None) -> None:
    rec = np.zeros(len(F), dtype=STL_RECORD)
    rec["v"] = V[F]
    n = len(F) if count is None else count
    path.write_bytes(header.ljust(80, b" ") + struct.pack("<I", n) + rec.tobytes())


def write_ply(path: Path, V: np.ndarray, polys: np.ndarray | list, fmt: str = "ascii", *,
              coord: str = "float", count_type: str = "uchar", index: str = "int",
              face_prop: str = "vertex_indices", extra: bool = True,
              declared_vertices: int | None = None) -> None:
    """A PLY with optional extra vertex properties (normal, colour) and a trailing edge element."""
    codes = {"float": "f", "double": "d", "uchar": "B", "ushort": "H", "int": "i", "uint": "I",
             "short": "h", "char": "b"}
    vprops = [("x", coord), ("y", coord), ("z", coord)]
    if extra:
        vprops = [("nx", "float")] + vprops + [("red", "uchar")]
    nv = len(V) if declared_vertices is None else declared_vertices
    head = ["ply", f"format {fmt} 1.0", "comment made by the tests", f"element vertex {nv}"]
    head += [f"property {t} {n}" for n, t in vprops]
    head += [f"element face {len(polys)}", f"property list {count_type} {index} {face_prop}"]
    if extra:
        head += ["element edge 1", "property int vertex1", "property int vertex2"]
    head.append("end_header")
    text = ("\n".join(head) + "\n").encode()

    def vrow(v: np.ndarray) -> list:
        vals = [float(v[0]), float(v[1]), float(v[2])]
        return [0.5] + vals + [200] if extra else vals

    if fmt == "ascii":
        body = [" ".join(repr(x) if isinstance(x, float) else str(x) for x in vrow(v)) for v in V]
        body += [f"{len(p)} " + " ".join(str(int(i)) for i in p) for p in polys]
        if extra:
            body.append("0 1")
        path.write_bytes(text + ("\n".join(body) + "\n").encode())
        return
    bo = "<" if fmt == "binary_little_endian" else ">"
    vfmt = bo + "".join(codes[t] for _, t in vprops)
    chunks = [struct.pack(vfmt, *vrow(v)) for v in V]
    for p in polys:
        chunks.append(struct.pack(bo + codes[count_type] + codes[index] * len(p), len(p),
                                  *(int(i) for i in p)))
    if extra:
        chunks.append(struct.pack(bo + "ii", 0, 1))
    path.write_bytes(text + b"".join(chunks))


def obj_text(V: np.ndarray, polys: np.ndarray | list) -> str:
    return ("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
            + "".join("f " + " ".join(str(int(i) + 1) for i in p) + "\n" for p in polys))


def problem(excinfo: pytest.ExceptionInfo) -> str:
    return excinfo.value.problem


# ---------------------------------------------------------------------------------------------
# Round trips
# ---------------------------------------------------------------------------------------------


def test_grid_construction() -> None:
    V, F, Q = grid(4)
    assert V.shape == (25, 3) and F.shape == (32, 3) and Q.shape == (16, 4)


def test_write_obj_round_trip(tmp_path: Path) -> None:
    V, F, _ = grid(4)
    path = tmp_path / "grid.obj"
    write_obj(path, V, F, header="made by\nthe tests")
    text = path.read_text()
    assert text.startswith("# made by\n# the tests\n")
    assert text.count("\nv ") == 25 and text.count("\nf ") == 32
    V2, F2 = read_mesh(path)
    assert V2.dtype == np.float64 and F2.dtype == np.int64
    np.testing.assert_allclose(V2, V, rtol=1e-8)
    np.testing.assert_array_equal(F2, F)
    assert not [p for p in tmp_path.iterdir() if p.name != "grid.obj"]


def test_write_obj_2d_vertices_get_zero_z(tmp_path: Path) -> None:
    V, F, _ = grid(2)
    write_obj(tmp_path / "flat.obj", V[:, :2], F)
    V2, F2 = read_mesh(tmp_path / "flat.obj")
    np.testing.assert_allclose(V2[:, :2], V[:, :2], rtol=1e-8)
    assert np.all(V2[:, 2] == 0)
    np.testing.assert_array_equal(F2, F)


def test_write_obj_is_atomic(tmp_path: Path) -> None:
    V, F, _ = grid(3)
    path = tmp_path / "keep.obj"
    write_obj(path, V, F)
    before = path.read_bytes()
    bad_faces = F.astype(object)
    bad_faces[-1, 2] = "not a number"  # formatting fails after the vertices were written
    with pytest.raises(TypeError):
        write_obj(path, V * 2, bad_faces)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["keep.obj"]  # no temporary left behind
    with pytest.raises(ValueError):
        write_obj(path, V[:, :1], F)
    assert path.read_bytes() == before


def test_write_obj_wrong_shapes(tmp_path: Path) -> None:
    V, F, _ = grid(1)
    with pytest.raises(ValueError):
        write_obj(tmp_path / "x.obj", V, F[:, :2])
    assert not list(tmp_path.iterdir())


def test_obj_corner_forms_comments_and_ignored_statements(tmp_path: Path) -> None:
    V, F, _ = grid(1)  # 4 vertices, 2 faces (0, 1, 3), (0, 3, 2)
    text = "\n".join([
        "# exported", "mtllib grid.mtl", "o grid", "g part",
        *(f"v {x!r} {y!r} {z!r}   # vertex" for x, y, z in V.tolist()),
        "vt 0 0", "vt 1 0", "vt 1 1", "vn 0 0 1", "s off", "usemtl skin",
        "f 1/1/1 2/2/1 4/3/1",
        "f 1//1 4//1 3//1",
    ]) + "\n"
    (tmp_path / "forms.obj").write_text(text)
    V2, F2 = read_mesh(tmp_path / "forms.obj")
    np.testing.assert_allclose(V2, V)
    np.testing.assert_array_equal(F2, F)


def test_a_plain_obj_read_in_bulk_equals_the_general_parser(tmp_path: Path) -> None:
    V, F, _ = grid(6)
    V = V + np.random.default_rng(3).normal(scale=0.01, size=V.shape)
    write_obj(tmp_path / "plain.obj", V, F, header="plain")
    data = (tmp_path / "plain.obj").read_bytes()
    assert mesh_io._parse_plain_obj(data.split(b"\n", 1)[1]) is not None, "the bulk path reads it"
    # one ignored statement sends the same file through the general parser
    (tmp_path / "general.obj").write_bytes(b"o grid\n" + data)
    assert mesh_io._parse_plain_obj(b"o grid\n" + data) is None
    Vp, Fp = read_mesh(tmp_path / "plain.obj")
    Vg, Fg = read_mesh(tmp_path / "general.obj")
    np.testing.assert_array_equal(Vp, Vg)
    np.testing.assert_array_equal(Fp, Fg)
    np.testing.assert_array_equal(Fp, F)


@pytest.mark.parametrize("text", [
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",          # a quad
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/1 2/2 3/3\n",               # corners with texture numbers
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nf -3 -2 -1\n",                  # relative numbers
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n",                     # a vertex that does not exist
    "v 0 0 0 1\nv 1 0 0\nv 1 1 0 1\nf 1 2 3\n",                 # w coordinates (a record of 5, one of 3)
    "v 0 0 0\nvn 0 0 1\nv 1 0 0\nv 1 1 0\nf 1 2 3\n",           # another statement
    "v 0 0 x\nv 1 0 0\nv 1 1 0\nf 1 2 3\n",                     # a bad number
])
def test_anything_but_a_plain_obj_goes_to_the_general_parser(text: str) -> None:
    assert mesh_io._parse_plain_obj(text.encode()) is None


def test_obj_crlf_and_uppercase_extension(tmp_path: Path) -> None:
    V, F, _ = grid(2)
    (tmp_path / "GRID.OBJ").write_bytes(obj_text(V, F).replace("\n", "\r\n").encode())
    V2, F2 = read_mesh(tmp_path / "GRID.OBJ")
    np.testing.assert_allclose(V2, V)
    np.testing.assert_array_equal(F2, F)


def test_obj_quads_are_fan_triangulated(tmp_path: Path) -> None:
    V, F, Q = grid(4)
    (tmp_path / "quads.obj").write_text(obj_text(V, Q))
    V2, F2 = read_mesh(tmp_path / "quads.obj")
    assert V2.shape == (25, 3) and F2.shape == (32, 3)
    np.testing.assert_array_equal(F2, F)


def test_obj_pentagon_fans_from_first_corner(tmp_path: Path) -> None:
    angles = np.arange(5) * 2 * np.pi / 5
    V = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(5)])
    (tmp_path / "pent.obj").write_text(obj_text(V, [[0, 1, 2, 3, 4]]))
    _, F2 = read_mesh(tmp_path / "pent.obj")
    np.testing.assert_array_equal(F2, [[0, 1, 2], [0, 2, 3], [0, 3, 4]])


def test_obj_negative_indices_are_relative(tmp_path: Path) -> None:
    V, F, _ = grid(1)
    # Each face follows only the vertices defined so far: -1 is the latest one.
    text = "\n".join([
        *(f"v {x!r} {y!r} {z!r}" for x, y, z in V[:2].tolist()),
        "v " + " ".join(map(repr, V[3].tolist())),
        "f -3 -2 -1",  # 0, 1, 2 (the file's third vertex is grid vertex 3)
        "v " + " ".join(map(repr, V[2].tolist())),
        "f -4 -2 -1",  # 0, 2, 3
    ]) + "\n"
    (tmp_path / "rel.obj").write_text(text)
    V2, F2 = read_mesh(tmp_path / "rel.obj")
    np.testing.assert_allclose(V2, V[[0, 1, 3, 2]])
    np.testing.assert_array_equal(F2, [[0, 1, 2], [0, 2, 3]])


@pytest.mark.parametrize("header_line", [False, True])
def test_off_round_trip_with_quads_and_colours(tmp_path: Path, header_line: bool) -> None:
    V, F, Q = grid(4)
    write_off(tmp_path / "grid.off", V, Q, colours=True, header_line=header_line)
    V2, F2 = read_mesh(tmp_path / "grid.off")
    np.testing.assert_allclose(V2, V)
    np.testing.assert_array_equal(F2, F)


@pytest.mark.parametrize("binary", [False, True])
def test_stl_round_trip_merges_to_the_grid(tmp_path: Path, binary: bool) -> None:
    V, F, _ = grid(4)
    path = tmp_path / "grid.stl"
    (write_stl_binary if binary else write_stl_ascii)(path, V, F)
    V2, F2 = read_mesh(path)
    assert V2.shape == (96, 3) and F2.shape == (32, 3)  # STL repeats each corner
    cleaned = clean_mesh(V2, F2)
    assert len(cleaned.V) == 25 and cleaned.merged == 96 - 25
    # Same triangles, corner for corner, in the same order (float32 precision for binary).
    np.testing.assert_allclose(cleaned.V[cleaned.F], V[F], atol=1e-6 if binary else 0)


def test_binary_stl_whose_header_starts_with_solid(tmp_path: Path) -> None:
    V, F, _ = grid(2)
    write_stl_binary(tmp_path / "solid.stl", V, F, header=b"solid but binary")
    V2, F2 = read_mesh(tmp_path / "solid.stl")
    assert F2.shape == (8, 3)
    np.testing.assert_allclose(V2, V[F].reshape(-1, 3), atol=1e-6)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("types", [("float", "uchar", "int", "vertex_indices"),
                                   ("double", "uint", "uint", "vertex_index"),
                                   ("float", "ushort", "short", "vertex_indices")])
def test_ply_round_trip(tmp_path: Path, fmt: str, types: tuple[str, str, str, str]) -> None:
    coord, count_type, index, face_prop = types
    V, F, _ = grid(4)
    write_ply(tmp_path / "grid.ply", V, F, fmt, coord=coord, count_type=count_type, index=index,
              face_prop=face_prop)
    V2, F2 = read_mesh(tmp_path / "grid.ply")
    np.testing.assert_allclose(V2, V, atol=1e-6 if coord == "float" else 0)
    np.testing.assert_array_equal(F2, F)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_quads_and_mixed_polygons(tmp_path: Path, fmt: str) -> None:
    V, F, Q = grid(4)
    write_ply(tmp_path / "quads.ply", V, Q, fmt, extra=False)
    np.testing.assert_array_equal(read_mesh(tmp_path / "quads.ply")[1], F)
    # Mixed: the first quad as two triangles, the rest as quads.
    mixed = [F[0], F[1], *Q[1:]]
    write_ply(tmp_path / "mixed.ply", V, mixed, fmt)
    V2, F2 = read_mesh(tmp_path / "mixed.ply")
    np.testing.assert_allclose(V2, V, atol=1e-6)
    np.testing.assert_array_equal(F2, F)


# ---------------------------------------------------------------------------------------------
# Refusals and malformed files
# ---------------------------------------------------------------------------------------------


def test_unknown_extension_lists_supported_ones(tmp_path: Path) -> None:
    (tmp_path / "mesh.xyz").write_text("1 2 3\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "mesh.xyz")
    assert problem(exc) == "unreadable"
    assert "mesh.xyz" in str(exc.value) and ".obj" in str(exc.value) and ".ply" in str(exc.value)


def test_missing_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "absent.obj")
    assert problem(exc) == "unreadable" and "absent.obj" in str(exc.value)
    (tmp_path / "folder.stl").mkdir()
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "folder.stl")
    assert problem(exc) == "unreadable" and "directory" in str(exc.value)


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root reads anything")
def test_unreadable_permissions(tmp_path: Path) -> None:
    path = tmp_path / "locked.obj"
    path.write_text("v 0 0 0\n")
    path.chmod(0)
    try:
        with pytest.raises(MeshError) as exc:
            read_mesh(path)
        assert problem(exc) == "unreadable" and "permission" in str(exc.value)
    finally:
        path.chmod(0o644)


@pytest.mark.parametrize("ext", [".obj", ".off", ".stl", ".ply"])
def test_empty_file(tmp_path: Path, ext: str) -> None:
    (tmp_path / f"empty{ext}").write_bytes(b"")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / f"empty{ext}")
    assert problem(exc) == "empty"


def test_vertices_but_no_faces(tmp_path: Path) -> None:
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "points.obj")
    assert problem(exc) == "empty" and "3 vertices" in str(exc.value)
    V, _, _ = grid(1)
    write_off(tmp_path / "points.off", V, [])
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "points.off")
    assert problem(exc) == "empty"


def test_obj_face_index_out_of_range_names_the_line(tmp_path: Path) -> None:
    lines = [f"v {i} {i % 3} 0" for i in range(10)] + ["# faces"] * 6 + ["f 1 2 12"]
    (tmp_path / "mesh.obj").write_text("\n".join(lines) + "\n")  # the face is line 17
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "mesh.obj")
    assert problem(exc) == "bad_index"
    message = str(exc.value)
    assert message.startswith("mesh.obj: line 17:") and "vertex 12" in message
    assert "10 vertices" in message


def test_obj_zero_and_bad_relative_index(tmp_path: Path) -> None:
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "zero.obj")
    assert problem(exc) == "bad_index" and "line 4" in str(exc.value)
    (tmp_path / "rel.obj").write_text("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "rel.obj")
    assert problem(exc) == "bad_index" and "line 3" in str(exc.value) and "-3" in str(exc.value)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_ply_and_off_index_out_of_range(tmp_path: Path, fmt: str) -> None:
    V, F, _ = grid(2)
    bad = F.copy()
    bad[5, 1] = 40
    write_ply(tmp_path / "bad.ply", V, bad, fmt)
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "bad.ply")
    assert problem(exc) == "bad_index" and "vertex 40" in str(exc.value)
    if fmt == "ascii":  # vertex line 10 of the body follows 15 header lines: face 5 is line 30
        assert "line 30" in str(exc.value)
    else:
        assert "face 5" in str(exc.value)
    write_off(tmp_path / "bad.off", V, bad)  # 4 header lines + 9 vertices: face 5 is line 19
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "bad.off")
    assert problem(exc) == "bad_index" and "line 19" in str(exc.value)


def test_face_with_two_corners(tmp_path: Path) -> None:
    (tmp_path / "two.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "two.obj")
    assert "line 5" in str(exc.value) and "3 corners" in str(exc.value)
    V, _, _ = grid(1)
    write_off(tmp_path / "two.off", V, [[0, 1, 3], [0, 3]])
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "two.off")
    assert "line 10" in str(exc.value)  # 4 header lines, 4 vertices, then the second face


def test_garbage_tokens_name_the_line(tmp_path: Path) -> None:
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 zero\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "bad.obj")
    assert problem(exc) == "unreadable" and "line 2" in str(exc.value) and "zero" in str(exc.value)
    (tmp_path / "bad2.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 two 3\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "bad2.obj")
    assert "line 4" in str(exc.value)
    (tmp_path / "short.obj").write_text("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "short.obj")
    assert "line 2" in str(exc.value)


def test_invalid_utf8_names_the_line(tmp_path: Path) -> None:
    (tmp_path / "latin.obj").write_bytes(b"v 0 0 0\nv 1 0 0\n# caf\xe9\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "latin.obj")
    assert problem(exc) == "unreadable" and "line 3" in str(exc.value)


def test_truncated_binary_stl(tmp_path: Path) -> None:
    V, F, _ = grid(2)
    write_stl_binary(tmp_path / "cut.stl", V, F)
    data = (tmp_path / "cut.stl").read_bytes()
    (tmp_path / "cut.stl").write_bytes(data[:84 + 50 * 3 + 20])
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "cut.stl")
    assert problem(exc) == "unreadable" and "truncated" in str(exc.value)
    assert "8 triangles" in str(exc.value) and "face 3" in str(exc.value)


def test_binary_stl_claiming_ten_million_faces_is_refused_from_the_header(tmp_path: Path) -> None:
    V, F, _ = grid(1)
    write_stl_binary(tmp_path / "huge.stl", V, F, count=10_000_000)  # 2 records, not 10 million
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "huge.stl", max_faces=100_000)
    assert problem(exc) == "too_many_faces"
    assert "10000000" in str(exc.value) and "100000" in str(exc.value)
    (tmp_path / "huge.stl").write_bytes(b"\0" * 80 + struct.pack("<I", 10_000_000))  # no body
    with pytest.raises(MeshError) as exc:
        read_mesh(tmp_path / "huge.stl", max_faces=100_000)
    assert problem(exc) == "too_many_faces"


class _CountingFile:
    """A binary file that records how many bytes were read from it."""

    def __init__(self, real, log: list[int]) -> None:
        self._real, self._log = real, log

    def read(self, size: int = -1) -> bytes:
        chunk = self._real.read(size)
        self._log.append(len(chunk))
        return chunk

    def __enter__(self) -> _CountingFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self._real.close()


@pytest.mark.parametrize("ext", [".stl", ".ply"])
def test_too_many_faces_is_refused_before_the_body_is_read(tmp_path: Path, ext: str,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    V, F, _ = grid(60)  # 7 200 triangles: a body of 360 kB (STL) or 95 kB (PLY)
    path = tmp_path / f"big{ext}"
    if ext == ".stl":
        write_stl_binary(path, V, F)
    else:
        write_ply(path, V, F, "binary_little_endian", extra=False)
    log: list[int] = []
    monkeypatch.setattr(mesh_io, "open", lambda *a, **k: _CountingFile(open(*a, **k), log),
                        raising=False)
    with pytest.raises(MeshError) as exc:
        read_mesh(path, max_faces=1000)
    assert problem(exc) == "too_many_faces" and "7200" in str(exc.value)
    assert sum(log) <= 65536 < path.stat().st_size  # the header only


def test_too_many_faces_in_every_format(tmp_path: Path) -> None:
    V, F, Q = grid(4)
    (tmp_path / "g.obj").write_text(obj_text(V, Q))  # 16 quads = 32 triangles
    write_off(tmp_path / "g.off", V, Q)
    write_ply(tmp_path / "g.ply", V, F, "binary_little_endian")
    write_stl_ascii(tmp_path / "g.stl", V, F)
    for name in ("g.obj", "g.off", "g.ply", "g.stl"):
        assert len(read_mesh(tmp_path / name, max_faces=32)[1]) == 32
        with pytest.raises(MeshError) as exc:
            read_mesh(tmp_path / name, max_faces=31)
        assert problem(exc) == "too_many_faces" and "31" in str(exc.value), name


def test_ply_header_that_lies_about_counts(tmp_path: Path) -> None:
    V, F, _ = grid(2)
    for fmt in ("ascii", "binary_little_endian", "binary_big_endian"):
        write_ply(tmp_path / "lie.ply", V, F, fmt, declared_vertices=1_000_000_000)
        with pytest.raises(MeshError) as exc:
            read_mesh(tmp_path / "lie.ply")
        assert problem(exc) == "unreadable" and "vertex" in str(exc.value), fmt


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian"])
def test_truncated_binary_ply(tmp_path: Path, fmt: str) -> None:
    V, F, Q = grid(2)
    for polys in (F, [F[0], *Q[1:]]):  # uniform triangles, then mixed sizes
        write_ply(tmp_path / "cut.ply", V, polys, fmt, extra=False)
        data = (tmp_path / "cut.ply").read_bytes()
        (tmp_path / "cut.ply").write_bytes(data[:-7])
        with pytest.raises(MeshError) as exc:
            read_mesh(tmp_path / "cut.ply")
        assert problem(exc) == "unreadable" and "truncated" in str(exc.value)


def _valid_files(tmp_path: Path) -> dict[str, bytes]:
    V, F, Q = grid(2)
    write_obj(tmp_path / "v.obj", V, F)
    write_off(tmp_path / "v.off", V, Q)
    write_stl_ascii(tmp_path / "a.stl", V, F)
    write_stl_binary(tmp_path / "b.stl", V, F)
    write_ply(tmp_path / "a.ply", V, F, "ascii")
    write_ply(tmp_path / "b.ply", V, [F[0], *Q[1:]], "binary_little_endian")
    return {p.name: p.read_bytes() for p in tmp_path.iterdir()}


def test_truncations_and_garbage_raise_mesh_error_only(tmp_path: Path) -> None:
    files = _valid_files(tmp_path)
    rng = np.random.default_rng(7)
    work = tmp_path / "fuzz"
    work.mkdir()
    for name, data in files.items():
        ext = Path(name).suffix
        cuts = sorted({1, 3, 10, 40, 84, 85, 100, len(data) // 2, len(data) - 1,
                       *rng.integers(1, len(data), 6).tolist()})
        variants = [data[:c] for c in cuts if c < len(data)]
        garbage = bytearray(data)
        for pos in rng.integers(0, len(data), 12):
            garbage[pos] = rng.integers(0, 256)
        variants += [bytes(garbage), rng.bytes(300), b"\x00" * 200, b"solid\n" + rng.bytes(100),
                     b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n"]
        for i, blob in enumerate(variants):
            path = work / f"{i}{ext}"
            path.write_bytes(blob)
            try:
                read_mesh(path)
            except MeshError:
                pass  # a (possibly lucky) successful read is fine too; anything else fails


@pytest.mark.timing
def test_big_obj_reads_fast(tmp_path: Path) -> None:
    import time

    V, F, _ = grid(100)  # 20 000 triangles
    write_obj(tmp_path / "big.obj", V, F)
    start = time.perf_counter()
    V2, F2 = read_mesh(tmp_path / "big.obj")
    elapsed = time.perf_counter() - start
    assert F2.shape == (20_000, 3) and V2.shape == (101 * 101, 3)
    assert elapsed < 1.0  # ≈ 0.05 s: the parse is vectorized, not a loop over lines
