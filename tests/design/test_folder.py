"""The design folder: written atomically, read back with its contract checked."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import ribbond.design.folder as folder_mod
from ribbond.design.folder import DESIGN_FILES, read_design_folder, write_design_folder
from tests.design.test_format import grid, make_design


def mesh() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 3×3 grid (8 counter-clockwise faces) and its flat copy: x, y scaled by 1.2 and shifted."""
    V, F = grid(3)
    return V, F, 1.2 * V[:, :2] + np.array([20.0, 30.0])


def write(out: Path, **changes: object) -> Path:
    V, F, P = mesh()
    args: dict[str, object] = dict(target_V=V, target_F=F, flat_V=P, design=make_design(len(F)))
    args.update(changes)
    return write_design_folder(out, **args)  # type: ignore[arg-type]


def snapshot(path: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(path.iterdir())}


def hidden_siblings(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir() if p.name.startswith("."))


def test_round_trip(tmp_path: Path) -> None:
    V, F, P = mesh()
    design = make_design(len(F), converged=True)
    out = write_design_folder(tmp_path / "saddle", target_V=V, target_F=F, flat_V=P, design=design,
                              extra_files={"preview.svg": b"<svg/>"})
    assert out == tmp_path / "saddle"
    assert sorted(p.name for p in out.iterdir()) == ["design.json", "flat.obj", "preview.svg", "target.obj"]
    got = read_design_folder(out)
    assert got.path == out and got.design == design
    assert np.array_equal(got.target_F, F) and got.target_F.dtype.kind == "i"
    assert np.allclose(got.target_V, V, rtol=1e-9, atol=1e-12)
    assert got.flat_V.shape == (9, 2) and np.allclose(got.flat_V, P, rtol=1e-9, atol=1e-12)
    assert not got.flat_V.flags.writeable
    # flat.obj lies in z = 0 and shares the faces of target.obj line for line
    flat, target = (out / "flat.obj").read_text(), (out / "target.obj").read_text()
    assert all(line.split()[3] == "0" for line in flat.splitlines() if line.startswith("v "))
    faces = [line for line in target.splitlines() if line.startswith("f ")]
    assert faces == [line for line in flat.splitlines() if line.startswith("f ")]
    assert faces[0] == "f 1 2 5"  # 1-based
    assert hidden_siblings(out) == []


def test_replaces_a_previous_design(tmp_path: Path) -> None:
    out = write(tmp_path / "d", extra_files={"front.gcode": b"G28\n"})
    V, F, P = mesh()
    write(out, flat_V=P * 1.5)
    assert "front.gcode" not in snapshot(out)  # the folder is replaced, not merged
    assert np.allclose(read_design_folder(out).flat_V, P * 1.5)
    assert hidden_siblings(out) == []


def test_empty_directory_is_fine(tmp_path: Path) -> None:
    (tmp_path / "d").mkdir()
    write(tmp_path / "d")
    assert read_design_folder(tmp_path / "d").design.faces.count == 8


def test_negative_flat_face_is_refused(tmp_path: Path) -> None:
    V, F, P = mesh()
    F = F.copy()
    F[5] = F[5, ::-1]  # clockwise
    F[6] = F[6, ::-1]
    with pytest.raises(ValueError, match=r"flat_V: 2 face\(s\) without positive signed area.*first: 5 \(.*6 \("):
        write(tmp_path / "d", target_F=F)
    assert not (tmp_path / "d").exists() and list(tmp_path.iterdir()) == []


def test_mirrored_flat_is_refused(tmp_path: Path) -> None:
    V, F, P = mesh()
    with pytest.raises(ValueError, match=r"8 face\(s\) without positive signed area"):
        write(tmp_path / "d", flat_V=P * np.array([-1.0, 1.0]))


@pytest.mark.parametrize("changes, pattern", [
    (dict(flat_V=np.zeros((8, 2))), r"flat_V has 8 vertices but target_V has 9"),
    (dict(design=make_design(7)), r"the mesh has 8 faces but design.json has 7"),
    (dict(target_F=np.array([[0, 1, 9]])), r"target_F refers to vertices outside 0..8"),
    (dict(extra_files={"notes.txt": b"x"}), r"extra_files: 'notes.txt' is not a file of the design format"),
])
def test_inconsistent_inputs_are_refused(tmp_path: Path, changes: dict[str, object], pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        write(tmp_path / "d", **changes)
    assert list(tmp_path.iterdir()) == []


def test_failure_while_writing_keeps_the_previous_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = write(tmp_path / "d", extra_files={"preview.png": b"\x89PNG"})
    before = snapshot(out)

    def broken(design: object) -> str:
        raise OSError("disk full")

    monkeypatch.setattr(folder_mod, "design_to_json", broken)
    V, F, P = mesh()
    with pytest.raises(OSError, match="disk full"):
        write(out, flat_V=P * 2)
    assert snapshot(out) == before
    assert hidden_siblings(out) == []


def test_failure_during_the_swap_restores_the_previous_folder(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    out = write(tmp_path / "d")
    before = snapshot(out)
    real_rename = folder_mod.os.rename

    def rename(src: object, dst: object) -> None:
        if ".tmp-" in str(src):  # moving the new folder in
            raise OSError("interrupted")
        real_rename(src, dst)

    monkeypatch.setattr(folder_mod.os, "rename", rename)
    V, F, P = mesh()
    with pytest.raises(OSError, match="interrupted"):
        write(out, flat_V=P * 2)
    assert snapshot(out) == before
    assert hidden_siblings(out) == []


def test_an_interrupted_swap_is_recovered_by_the_next_write(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    out = write(tmp_path / "d")
    before = snapshot(out)
    # as if killed after moving the old folder aside, with a half-written temporary folder around
    out.rename(tmp_path / ".d.bak-0123456789ab")
    (tmp_path / ".d.tmp-ba9876543210").mkdir()
    (tmp_path / ".d.tmp-ba9876543210" / "target.obj").write_text("v 0 0")
    (tmp_path / "notes.d.bak-0123456789ab").mkdir()  # not ours: left alone
    monkeypatch.setattr(folder_mod, "design_to_json", lambda design: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        write(out)  # fails, but only after the recovery
    assert snapshot(out) == before
    assert hidden_siblings(out) == []
    assert (tmp_path / "notes.d.bak-0123456789ab").is_dir()


def test_foreign_directory_is_not_replaced(tmp_path: Path) -> None:
    home = tmp_path / "home"
    home.mkdir()
    (home / "thesis.tex").write_text("precious")
    (home / "design.json").write_text("{}")
    with pytest.raises(ValueError, match=r"home: exists and is not a design folder \(it holds thesis.tex\)"):
        write(home)
    assert sorted(p.name for p in home.iterdir()) == ["design.json", "thesis.tex"]
    sub = tmp_path / "withsub"
    (sub / "target.obj").mkdir(parents=True)  # a directory where a file belongs is foreign too
    with pytest.raises(ValueError, match="not a design folder"):
        write(sub)
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="not a directory"):
        write(tmp_path / "file")
    assert hidden_siblings(home) == []


def test_known_files_are_the_documented_ones() -> None:
    assert DESIGN_FILES == {"target.obj", "flat.obj", "design.json", "front.gcode", "back.gcode",
                            "combined.gcode", "preview.svg", "preview.png",
                            "deployed.obj", "deployed.png"}           # format 2


def _replace_line(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def test_reader_checks_the_contract(tmp_path: Path) -> None:
    out = write(tmp_path / "d")
    good = snapshot(out)

    def broken(file: str, old: str, new: str, pattern: str) -> None:
        for name, data in good.items():
            (out / name).write_bytes(data)
        _replace_line(out / file, old, new)
        with pytest.raises(ValueError, match=pattern):
            read_design_folder(out)

    broken("flat.obj", "f 1 2 5\n", "f 1 5 2\n", r"flat\.obj: face 0 differs from target\.obj's")
    broken("flat.obj", "f 1 2 5\n", "", r"flat\.obj: 7 faces but target\.obj has 8")
    broken("flat.obj", "v 20 30 0\n", "", r"flat\.obj: 8 vertices but target\.obj has 9")
    broken("flat.obj", "v 20 30 0\n", "v 20 30 0.5\n", r"flat\.obj: vertex 0 has z = 0\.5")
    broken("flat.obj", "v 20 30 0\n", "v 80 80 0\n", r"flat\.obj: .* without positive signed area.*first: 0 ")
    broken("target.obj", "f 1 2 5\nf 1 5 4\n", "f 1 2 5\nf 1 5 4\nf 2 3 6\n", r"8 faces but target\.obj has 9")
    broken("target.obj", "f 1 2 5\n", "f 1 2 99\n", r"target\.obj: face 0 refers to a vertex outside 1..9")
    broken("target.obj", "f 1 2 5\n", "f 1 2 5 4\n", r"target\.obj: every face must be a triangle")
    broken("design.json", '"faces": 8', '"faces": 9', r"design\.json: invalid design: report\.faces = 9")
    for name, data in good.items():
        (out / name).write_bytes(data)
    read_design_folder(out)
    (out / "flat.obj").unlink()
    with pytest.raises(ValueError, match=r"flat\.obj: missing"):
        read_design_folder(out)
    (out / "design.json").unlink()
    with pytest.raises(ValueError, match=r"design\.json: missing: not a design folder"):
        read_design_folder(out)


def test_sliver_that_rounding_flattens_is_refused(tmp_path: Path) -> None:
    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0]])
    F = np.array([[0, 1, 2]])
    P = np.array([[100.0, 100.0], [200.0, 100.0], [150.0, 100.000000001]])  # area 5e-8 > 0, lost at %.9g
    with pytest.raises(ValueError, match=r"does not read back.*flat\.obj: 1 face\(s\) without positive"):
        write(tmp_path / "d", target_V=V, target_F=F, flat_V=P, design=make_design(1, ribbons=False))
    assert list(tmp_path.iterdir()) == []
