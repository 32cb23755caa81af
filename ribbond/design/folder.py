"""The design folder (``/work/shared/design-format.md``): written atomically, read back with its contract checked.

``write_design_folder`` builds the whole folder in a hidden sibling directory, checks what it wrote
by reading it back exactly as a consumer would, and only then swaps it into place; the previous
folder is kept as a hidden sibling backup until the new one is in, and restored on any failure. A
directory holding anything but design files is never replaced.

``read_design_folder`` reads ``target.obj``, ``flat.obj`` and ``design.json`` and checks the contract:
the same vertex count and the same faces (order and winding) in both meshes, ``flat.obj`` at z = 0
with every face counter-clockwise, and one ``design.json`` face per mesh face.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ribbond.design.format import Design, design_from_json, design_to_json
from ribbond.mesh.files import write_obj

#: The files a design folder may hold (the format document's table).
CORE_FILES = ("target.obj", "flat.obj", "design.json")
OPTIONAL_FILES = ("front.gcode", "back.gcode", "combined.gcode", "preview.svg", "preview.png",
                  "deployed.obj", "deployed.png")
DESIGN_FILES = frozenset(CORE_FILES + OPTIONAL_FILES)

_TMP = ".tmp-"
_BAK = ".bak-"
_DEL = ".del-"


@dataclass(frozen=True, eq=False)
class DesignFolder:
    """A design folder as read from disk; the arrays are read-only."""

    path: Path
    target_V: np.ndarray  # (n, 3) float, mm
    target_F: np.ndarray  # (m, 3) int, 0-based, the engine's order
    flat_V: np.ndarray  # (n, 2) float, mm, front-side print coordinates
    design: Design


# ---------------------------------------------------------------------------------------------
# reading OBJ files (our own: 'v x y z' and 'f a b c' lines)


def _read_text(path: Path, when_missing: str) -> str:
    """A design file's text; ValueError naming the file when it is missing or unreadable."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{path}: missing: {when_missing}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read ({exc})") from None


def _read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) and 0-based triangles (m, 3) of an OBJ file; ValueError naming the file.

    Indices are not checked against the vertex count here (see ``_check_indices``).
    """
    text = _read_text(path, "not a complete design folder")
    v_rows: list[str] = []
    f_rows: list[str] = []
    for line in text.splitlines():
        if line.startswith("v "):
            v_rows.append(line[2:])
        elif line.startswith("f "):
            f_rows.append(line[2:])
    try:
        v_tokens = " ".join(v_rows).split()
        if len(v_tokens) != 3 * len(v_rows):
            raise ValueError("a vertex line does not hold exactly three coordinates")
        V = np.array(v_tokens, dtype=float).reshape(-1, 3)
    except ValueError as exc:
        raise ValueError(f"{path}: bad vertex line: {exc}") from None
    joined = " ".join(f_rows)
    tokens = joined.split()
    if len(tokens) != 3 * len(f_rows):
        raise ValueError(f"{path}: every face must be a triangle ('f a b c')")
    if "/" in joined:
        tokens = [t.split("/", 1)[0] for t in tokens]
    try:
        F = np.array(tokens, dtype=np.int64).reshape(-1, 3) - 1
    except ValueError as exc:
        raise ValueError(f"{path}: bad face line: {exc}") from None
    if not np.isfinite(V).all():
        raise ValueError(f"{path}: vertex {int(np.flatnonzero(~np.isfinite(V).all(axis=1))[0])} is not finite")
    return V, F


def _check_indices(F: np.ndarray, n: int, path: Path) -> None:
    if F.size and (F.min() < 0 or F.max() >= n):
        bad = int(np.flatnonzero(((F < 0) | (F >= n)).any(axis=1))[0])
        raise ValueError(f"{path}: face {bad} refers to a vertex outside 1..{n}")


# ---------------------------------------------------------------------------------------------
# checks shared by writing and reading


def signed_areas(flat_V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Signed area of each face of the flat mesh; positive when counter-clockwise seen from +z."""
    a, b, c = flat_V[F[:, 0]], flat_V[F[:, 1]], flat_V[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _check_flat_areas(flat_V: np.ndarray, F: np.ndarray, where: str) -> None:
    area = signed_areas(flat_V, F)
    bad = np.flatnonzero(~(area > 0))
    if bad.size:
        first = ", ".join(f"{int(i)} ({area[i]:.3g} mm²)" for i in bad[:5])
        raise ValueError(f"{where}: {bad.size} face(s) without positive signed area (every face must be "
                         f"counter-clockwise seen from +z); first: {first}")


def _check_face_count(m: int, design: Design, where: str) -> None:
    if design.faces.count != m:
        raise ValueError(f"{where}: the mesh has {m} faces but design.json has {design.faces.count} "
                         "(faces.sigma1 and the other per-face fields need one value per face)")


def _as_arrays(target_V: np.ndarray, target_F: np.ndarray, flat_V: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    V = np.asarray(target_V, dtype=float)
    F = np.asarray(target_F)
    P = np.asarray(flat_V, dtype=float)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"target_V must have shape (n, 3), got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise ValueError(f"target_F must have shape (m, 3) with m >= 1, got {F.shape}")
    if not np.issubdtype(F.dtype, np.integer):
        raise ValueError(f"target_F must hold integer vertex indices, got {F.dtype}")
    F = F.astype(np.int64)
    if P.ndim != 2 or P.shape[1] not in (2, 3):
        raise ValueError(f"flat_V must have shape (n, 2), got {P.shape}")
    if P.shape[1] == 3:
        if np.any(P[:, 2] != 0):
            raise ValueError("flat_V has a z column that is not 0: the flat surface lies in z = 0")
        P = P[:, :2]
    if len(P) != len(V):
        raise ValueError(f"flat_V has {len(P)} vertices but target_V has {len(V)}: the flat mesh must "
                         "have the same vertices (count and order) as the target")
    for name, X in (("target_V", V), ("flat_V", P)):
        if not np.isfinite(X).all():
            raise ValueError(f"{name}[{int(np.flatnonzero(~np.isfinite(X).all(axis=1))[0])}] is not finite")
    if F.min() < 0 or F.max() >= len(V):
        raise ValueError(f"target_F refers to vertices outside 0..{len(V) - 1}")
    return V, F, P


# ---------------------------------------------------------------------------------------------
# reading


def read_design_folder(path: Path) -> DesignFolder:
    """Read a design folder and check its contract.

    Raises
    ------
    ValueError
        naming the file and the problem: a missing or unreadable file, invalid ``design.json``,
        vertex counts or faces that differ between ``target.obj`` and ``flat.obj``, ``flat.obj``
        off z = 0 or with a face that is not counter-clockwise, a face count that differs from
        ``design.json``.
    """
    path = Path(path)
    if not path.is_dir():
        raise ValueError(f"{path}: not a directory (a design folder is a directory)")
    json_path = path / "design.json"
    text = _read_text(json_path, "not a design folder")
    design = design_from_json(text, where=str(json_path))
    target_path, flat_path = path / "target.obj", path / "flat.obj"
    V, F = _read_obj(target_path)
    Q, G = _read_obj(flat_path)
    if len(F) == 0:
        raise ValueError(f"{target_path}: no faces")
    _check_indices(F, len(V), target_path)
    if len(Q) != len(V):
        raise ValueError(f"{flat_path}: {len(Q)} vertices but {target_path.name} has {len(V)}: "
                         "both meshes share their vertices (count and order)")
    if G.shape != F.shape or not np.array_equal(G, F):
        if G.shape != F.shape:
            detail = f"{len(G)} faces but {target_path.name} has {len(F)}"
        else:
            detail = f"face {int(np.flatnonzero((G != F).any(axis=1))[0])} differs from {target_path.name}'s"
        raise ValueError(f"{flat_path}: {detail}: both meshes share their faces (order and winding)")
    scale = max(1.0, float(np.abs(Q[:, :2]).max(initial=0.0)))
    off = np.flatnonzero(np.abs(Q[:, 2]) > 1e-9 * scale)
    if off.size:
        raise ValueError(f"{flat_path}: vertex {int(off[0])} has z = {float(Q[off[0], 2])!r}: the flat surface lies in z = 0")
    P = np.ascontiguousarray(Q[:, :2])
    _check_flat_areas(P, F, str(flat_path))
    _check_face_count(len(F), design, str(path))
    for a in (V, F, P):
        a.setflags(write=False)
    return DesignFolder(path=path, target_V=V, target_F=F, flat_V=P, design=design)


# ---------------------------------------------------------------------------------------------
# writing


def _write_synced(path: Path, data: bytes) -> None:
    with open(path, "xb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):  # not every platform/file system syncs directories
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def _locked(directory: Path) -> Iterator[bool]:
    """Serialize writers (of this program) within ``directory`` with an advisory lock on it.

    Yields whether the lock is held (False where the platform has no advisory locks).
    """
    try:
        import fcntl
    except ImportError:
        yield False
        return
    fd = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield True
    finally:
        os.close(fd)  # releases the lock


def check_destination(out_dir: str | Path) -> None:
    """Refuse, before any work, a destination the design folder could not be written to: a file, a
    symbolic link, a directory that is not a design folder, or a parent that is not a writable
    directory (ValueError naming it). ``write_design_folder`` checks it again under its lock."""
    out_dir = Path(out_dir)
    _check_replaceable(out_dir)
    _check_parent(out_dir)


def _check_parent(out_dir: Path) -> None:
    """The nearest existing ancestor of ``out_dir`` is a directory we may write into."""
    parent = next((p for p in out_dir.absolute().parents if p.exists()), None)
    if parent is None:
        return
    if not parent.is_dir():
        raise ValueError(f"{out_dir}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{out_dir}: cannot write in {parent} (permission denied)")


def _check_replaceable(out_dir: Path) -> None:
    """Refuse to replace anything but a missing, empty or design directory."""
    if out_dir.is_symlink():
        raise ValueError(f"{out_dir}: is a symbolic link; give the directory itself")
    if not out_dir.exists():
        return
    if not out_dir.is_dir():
        raise ValueError(f"{out_dir}: exists and is not a directory; refusing to replace it")
    foreign = sorted(p.name for p in out_dir.iterdir() if p.name not in DESIGN_FILES or not p.is_file())
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        raise ValueError(f"{out_dir}: exists and is not a design folder (it holds {shown}); "
                         "refusing to replace it: choose another output directory or remove it")


def _siblings(out_dir: Path, kind: str) -> list[Path]:
    """Our hidden siblings of ``out_dir`` of one kind (temporary, backup, being deleted), oldest first."""
    pattern = re.compile(re.escape(f".{out_dir.name}{kind}") + r"[0-9a-f]{12}")
    found = []
    for p in out_dir.parent.iterdir():
        if pattern.fullmatch(p.name):
            with contextlib.suppress(OSError):
                found.append((p.lstat().st_mtime, p))
    return [p for _, p in sorted(found)]


def _recover(out_dir: Path) -> None:
    """Clean up after writers that were interrupted (called with the lock held).

    A writer stopped between moving the old folder aside and moving the new one in leaves no
    ``out_dir`` and a backup: the backup goes back in place. Temporary folders of dead writers and
    backups that were not deleted are removed.
    """
    if not out_dir.exists() and not out_dir.is_symlink():
        backups = _siblings(out_dir, _BAK)
        if backups:
            os.rename(backups[-1], out_dir)
    for kind in (_TMP, _BAK, _DEL):
        for p in _siblings(out_dir, kind):
            shutil.rmtree(p, ignore_errors=True)


def write_design_folder(out_dir: Path, *, target_V: np.ndarray, target_F: np.ndarray,
                        flat_V: np.ndarray, design: Design,
                        extra_files: Mapping[str, bytes] | None = None) -> Path:
    """Write ``target.obj``, ``flat.obj``, ``design.json`` (and ``extra_files``) into ``out_dir``, atomically.

    Parameters
    ----------
    out_dir : the design folder; created, or replaced if it is an (empty or) design folder.
    target_V, target_F : the target mesh, (n, 3) mm and (m, 3) 0-based faces in the engine's order.
    flat_V : (n, 2) the flat mesh in front-side print coordinates (same vertices, same faces).
    design : the content of ``design.json``; one face per mesh face.
    extra_files : more files of the format by name (``front.gcode``, ``preview.png``, …).

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    ValueError
        when the meshes or the design break the contract (the message names the first offending
        faces), when an extra file is not one of the format's, or when ``out_dir`` exists and holds
        anything else than design files. Nothing on disk changes then.
    OSError
        when writing fails; the previous folder (if any) is left as it was.
    """
    out_dir = Path(out_dir)
    V, F, P = _as_arrays(target_V, target_F, flat_V)
    _check_flat_areas(P, F, "flat_V")
    _check_face_count(len(F), design, "design")
    extra = dict(extra_files or {})
    for name in extra:
        if name not in OPTIONAL_FILES:
            raise ValueError(f"extra_files: {name!r} is not a file of the design format "
                             f"(one of {', '.join(OPTIONAL_FILES)})")
    if not out_dir.name or out_dir.name in (".", ".."):
        raise ValueError(f"{out_dir}: not a usable directory name")
    parent = out_dir.parent
    parent.mkdir(parents=True, exist_ok=True)

    with _locked(parent) as locked:
        if locked:  # other writers of ours are not running: leftovers are from interrupted ones
            _recover(out_dir)
        _check_replaceable(out_dir)
        tmp = parent / f".{out_dir.name}{_TMP}{secrets.token_hex(6)}"
        tmp.mkdir()
        try:
            header = "ribbond design: {} surface, mm"
            write_obj(tmp / "target.obj", V, F, header=header.format("target (deployed)"))
            write_obj(tmp / "flat.obj", P, F,
                      header=header.format("flat (pre-stretched), front-side print coordinates, z = 0"))
            files = {"design.json": design_to_json(design).encode(), **extra}
            _write_checked_swap(tmp, out_dir, files, "the design as written")
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    return out_dir


def _write_checked_swap(tmp: Path, out_dir: Path, files: dict[str, bytes], what: str) -> None:
    """Write ``files`` into ``tmp`` (synced), check that it reads back as a design folder (what a
    consumer will read; the OBJ precision must not flip a sliver face), and swap it in."""
    for name, data in files.items():
        _write_synced(tmp / name, bytes(data))
    _fsync_dir(tmp)
    try:
        read_design_folder(tmp)
    except ValueError as exc:
        raise ValueError(f"{what} does not read back: {exc}") from None
    _swap_in(tmp, out_dir)


def _swap_in(tmp: Path, out_dir: Path) -> None:
    """Move ``tmp`` to ``out_dir``; an existing ``out_dir`` is moved aside first and restored on failure."""
    parent = out_dir.parent
    if not out_dir.exists():
        os.rename(tmp, out_dir)
        _fsync_dir(parent)
        return
    backup = parent / f".{out_dir.name}{_BAK}{secrets.token_hex(6)}"
    os.rename(out_dir, backup)
    try:
        os.rename(tmp, out_dir)
    except BaseException:
        os.rename(backup, out_dir)
        raise
    _fsync_dir(parent)
    # Renamed first so that a partly deleted backup is never taken for one to restore.
    doomed = parent / f".{out_dir.name}{_DEL}{secrets.token_hex(6)}"
    with contextlib.suppress(OSError):
        os.rename(backup, doomed)
        backup = doomed
    shutil.rmtree(backup, ignore_errors=True)


def _link_or_copy(src: Path, dst: Path) -> None:
    """``dst`` as a hard link to ``src`` (nothing written twice); a copy where links are refused."""
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def replace_design_files(folder: Path, files: Mapping[str, bytes]) -> Path:
    """Replace some files of an existing design folder (``design.json``, ``deployed.obj``, …), atomically.

    The new folder is built in a hidden sibling: the files kept are hard-linked into it (never
    written again), the new ones written and synced; it is read back as a consumer would, then
    swapped in as ``write_design_folder`` does. On any failure the folder is left as it was.

    Parameters
    ----------
    folder : an existing design folder.
    files : the new content of each replaced file, by name; ``design.json`` and the optional files
        of the format (``OPTIONAL_FILES``); ``target.obj`` and ``flat.obj`` are never replaced here.

    Raises
    ------
    ValueError
        when ``folder`` is not a readable design folder, a name is not one of the files that may be
        replaced, or the folder as it would be does not read back (the message names the file).
    OSError
        when writing fails; the folder is left as it was.
    """
    folder = Path(folder)
    for name in files:
        if name != "design.json" and name not in OPTIONAL_FILES:
            raise ValueError(f"{name!r}: not a file of the design format that may be replaced "
                             f"(design.json or one of {', '.join(OPTIONAL_FILES)})")
    with _locked(folder.parent) as locked:
        if locked:
            _recover(folder)
        _check_replaceable(folder)
        read_design_folder(folder)                      # refuse to rebuild a folder that is not one
        tmp = folder.parent / f".{folder.name}{_TMP}{secrets.token_hex(6)}"
        tmp.mkdir()
        try:
            for old in folder.iterdir():
                if old.name not in files:
                    _link_or_copy(old, tmp / old.name)
            _write_checked_swap(tmp, folder, files, "the design as it would be written")
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    return folder
