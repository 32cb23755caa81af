"""Reading and writing triangle meshes: OBJ, OFF, STL (ASCII and binary) and PLY (ASCII and binary).

``read_mesh`` returns ``V`` (n, 3) float64 and ``F`` (m, 3) int64, 0-based, with polygons
fan-triangulated; it never merges vertices (``intake.clean_mesh`` does) and never judges the
surface (``intake.check_disk`` does). Every failure, whatever the file holds, is a
:class:`~ribbond.design.errors.MeshError` whose message names the file, the problem and where it
is (a line number for text formats, a face index for binary ones).

Parsing is vectorized: text formats are tokenized by whole-file regular expressions and converted
in bulk; binary STL and PLY are read with structured ``np.frombuffer`` dtypes. A Python loop runs
only to locate an error already detected and for binary PLY faces of mixed polygon sizes.
"""

from __future__ import annotations

import itertools
import os
import re
import stat
import struct
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .errors import MeshError

__all__ = ["SUPPORTED_EXTENSIONS", "read_mesh", "write_obj"]

#: File extensions ``read_mesh`` understands (compared case-insensitively).
SUPPORTED_EXTENSIONS = (".obj", ".off", ".ply", ".stl")

_TOKEN_OR_NEWLINE = re.compile(rb"[^ \t\r\n\f\v]+|\n")
_COMMENT = re.compile(rb"#[^\n]*")
_OBJ_RECORD = re.compile(rb"(?m)^[ \t]*([vf])[ \t]+([^\n]*)")
_XYZ_LINE = re.compile(
    rb"(?m)^[ \t\r\f\v]*([^ \t\r\n\f\v]+)[ \t\r\f\v]+([^ \t\r\n\f\v]+)[ \t\r\f\v]+([^ \t\r\n\f\v]+)")
_OBJ_CORNER_TAIL = re.compile(rb"/[^ \t\r\n\f\v]*")
_STL_VERTEX = re.compile(rb"(?i)vertex[ \t]+([^ \t\r\n\f\v]+)[ \t]+([^ \t\r\n\f\v]+)[ \t]+([^ \t\r\n\f\v]+)")
_PLY_HEADER_END = re.compile(rb"(?m)^end_header[ \t]*\r?\n")
_PLY_HEADER_LIMIT = 1 << 20  # a header longer than 1 MiB is not a header

#: PLY scalar types → numpy type codes (without byte order).
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


# ---------------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------------


def read_mesh(path: str | Path, *, max_faces: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh from an OBJ, OFF, STL or PLY file (chosen by extension).

    Parameters
    ----------
    path : str or Path
        the file; its extension (``.obj``, ``.off``, ``.stl``, ``.ply``, any case) picks the format.
    max_faces : int, optional
        refuse files with more triangles (after fan triangulation) than this, as early as possible:
        binary STL and PLY from the header count before the body is read.

    Returns
    -------
    V : (n, 3) float64 array
        vertex positions, as in the file (no merging; STL repeats each corner).
    F : (m, 3) int64 array
        triangles, 0-based indices into ``V``; polygons are fan-triangulated (v0, vk, vk+1).

    Raises
    ------
    MeshError
        ``"unreadable"`` (missing, not a file, unsupported extension, malformed or truncated
        content), ``"empty"`` (no vertices or no faces), ``"bad_index"`` (a face refers to a
        vertex the file does not have), ``"too_many_faces"`` (more than ``max_faces``).
    """
    V, F, _ = _read(path, max_faces)
    return V, F


def _obj_text(V: np.ndarray, F: np.ndarray, header: str | None) -> str:
    head = "".join(f"# {line}\n" for line in header.splitlines()) if header else ""
    # One C-level formatting call per block: no Python loop over rows.
    return (head + ("v %.9g %.9g %.9g\n" * len(V)) % tuple(V.ravel().tolist())
            + ("f %d %d %d\n" * len(F)) % tuple((F + 1).ravel().tolist()))


def obj_bytes(V: np.ndarray, F: np.ndarray, *, header: str | None = None) -> bytes:
    """An (n, 3) mesh with (m, 3) 0-based faces as the bytes of an OBJ file (as ``write_obj`` writes)."""
    V = np.asarray(V, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"obj_bytes: V must be (n, 3) and F (m, 3), got {V.shape} and {F.shape}")
    return _obj_text(V, F, header).encode()


def write_obj(path: str | Path, V: np.ndarray, F: np.ndarray, *, header: str | None = None) -> None:
    """Write a triangle mesh as OBJ, atomically (temporary file in the same folder, then rename).

    Parameters
    ----------
    path : str or Path
        the file to write; an existing file is replaced only once the new one is complete.
    V : (n, 3) or (n, 2) array
        vertex positions, written with ``%.9g``; a 2-column array gets z = 0.
    F : (m, 3) int array
        triangles, 0-based (written 1-based).
    header : str, optional
        text written as ``#`` comment lines at the top.

    Raises
    ------
    ValueError
        ``V`` or ``F`` has the wrong shape.
    OSError
        the file cannot be written (the previous file, if any, is left as it was).
    """
    path = Path(path)
    V = np.asarray(V)
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] not in (2, 3):
        raise ValueError(f"write_obj: V must be (n, 3) or (n, 2), got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        if not (F.size == 0 and F.ndim >= 1):
            raise ValueError(f"write_obj: F must be (m, 3), got shape {F.shape}")
        F = F.reshape(0, 3)
    if V.shape[1] == 2:
        V = np.column_stack([V, np.zeros(len(V), dtype=V.dtype if V.dtype != object else float)])

    directory = path.parent
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as out:
            out.write(_obj_text(V, F, header))
            out.flush()
            os.fsync(out.fileno())
        try:
            mode = stat.S_IMODE(os.stat(path).st_mode)
        except OSError:
            mode = 0o644
        os.chmod(tmp_name, mode)
        os.replace(tmp_name, path)
    except BaseException:
        try:
            os.unlink(tmp_name)
        except OSError:
            pass
        raise


# ---------------------------------------------------------------------------------------------
# File access and dispatch
# ---------------------------------------------------------------------------------------------


def _read(path: str | Path, max_faces: int | None) -> tuple[np.ndarray, np.ndarray, bytes]:
    """``read_mesh`` that also returns the file's bytes (for hashing by the intake)."""
    path = Path(path)
    name = path.name or str(path)
    ext = path.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        shown = f"'{path.suffix}'" if path.suffix else "no extension"
        raise MeshError("unreadable", f"{name}: unsupported file type ({shown}); supported: "
                                      f"{', '.join(SUPPORTED_EXTENSIONS)}")
    try:
        data = _read_bytes(path, name, ext, max_faces)
        if ext == ".obj":
            V, F = _parse_obj(data, name, max_faces)
        elif ext == ".off":
            V, F = _parse_off(data, name, max_faces)
        elif ext == ".stl":
            V, F = _parse_stl(data, name, max_faces)
        else:
            V, F = _parse_ply(data, name, max_faces)
    except MeshError:
        raise
    except Exception as exc:  # never let a malformed file escape as anything but MeshError
        raise MeshError("unreadable", f"{name}: cannot be read as {ext[1:].upper()}: "
                                      f"{type(exc).__name__}: {exc}") from exc
    if len(V) == 0:
        raise MeshError("empty", f"{name}: the file has no vertices")
    if len(F) == 0:
        raise MeshError("empty", f"{name}: the file has {len(V)} vertices but no faces")
    _check_max_faces(name, len(F), max_faces, "")
    return V, F, data


def _read_bytes(path: Path, name: str, ext: str, max_faces: int | None) -> bytes:
    """The file's bytes; binary STL/PLY headers are checked against ``max_faces`` first."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise _os_error(name, path, exc, "access") from None
    if stat.S_ISDIR(st.st_mode):
        raise MeshError("unreadable", f"{name}: is a directory, not a mesh file")
    if not stat.S_ISREG(st.st_mode):  # FIFOs and devices could block forever
        raise MeshError("unreadable", f"{name}: is not a regular file")
    try:
        with open(path, "rb") as fh:
            if ext == ".stl":
                head = fh.read(84)
                _precheck_stl(head, st.st_size, name, max_faces)
            elif ext == ".ply":
                head = fh.read(65536)
                while not _PLY_HEADER_END.search(head) and len(head) < _PLY_HEADER_LIMIT:
                    more = fh.read(65536)
                    if not more:
                        break
                    head += more
                _precheck_ply(head, name, max_faces)
            else:
                head = b""
            return head + fh.read()
    except OSError as exc:
        raise _os_error(name, path, exc, "read") from None


def _os_error(name: str, path: Path, exc: OSError, doing: str) -> MeshError:
    """The MeshError for an operating-system error while opening or reading a mesh file."""
    if isinstance(exc, FileNotFoundError):
        return MeshError("unreadable", f"{name}: no such file ({path})")
    if isinstance(exc, PermissionError):
        return MeshError("unreadable", f"{name}: permission denied ({path})")
    if isinstance(exc, IsADirectoryError):
        return MeshError("unreadable", f"{name}: is a directory, not a mesh file")
    return MeshError("unreadable", f"{name}: cannot {doing} the file: {exc.strerror or exc}")


def _check_max_faces(name: str, count: int, max_faces: int | None, what: str) -> None:
    if max_faces is not None and count > max_faces:
        raise MeshError("too_many_faces", f"{name}: {what}{count} faces, more than the limit of "
                                          f"{max_faces}")


# ---------------------------------------------------------------------------------------------
# Shared helpers
# ---------------------------------------------------------------------------------------------


def _line_of(data: bytes, offset: int) -> int:
    """1-based line number of a byte offset."""
    return data.count(b"\n", 0, offset) + 1


def _decode_check(data: bytes, name: str, start: int = 0) -> None:
    """Refuse text that is not UTF-8, naming the line."""
    try:
        data[start:].decode("utf-8")
    except UnicodeDecodeError as exc:
        pos = start + exc.start
        raise MeshError("unreadable", f"{name}: line {_line_of(data, pos)}: not valid UTF-8 text "
                                      f"(byte 0x{data[pos]:02x}); is this a binary file?") from None


def _strip_bom(data: bytes) -> bytes:
    return data[3:] if data.startswith(b"\xef\xbb\xbf") else data


def _floats(tokens: list[bytes] | np.ndarray) -> np.ndarray:
    """Bulk float conversion (raises ValueError on the first bad token)."""
    return np.fromiter(map(float, tokens), dtype=np.float64, count=len(tokens))


def _ints(tokens: list[bytes] | np.ndarray) -> np.ndarray:
    """Bulk int conversion (raises ValueError/OverflowError on the first bad token)."""
    return np.fromiter(map(int, tokens), dtype=np.int64, count=len(tokens))


def _ints_or_error(tokens: list[bytes] | np.ndarray, describe: Callable[[int], str]) -> np.ndarray:
    """Tokens as integers, or MeshError("unreadable", describe(index of the first bad token))."""
    try:
        return _ints(tokens)
    except (ValueError, OverflowError):
        raise MeshError("unreadable", describe(_first_bad(tokens, int))) from None


def _first_bad(tokens: list[bytes] | np.ndarray, convert: type) -> int:
    """Index of the first token ``convert`` rejects (error path only)."""
    for i, tok in enumerate(tokens):
        try:
            value = convert(tok)
            if convert is int and not -(2**63) <= value < 2**63:
                return i
        except (ValueError, OverflowError):
            return i
    return -1


def _show(tok: bytes) -> str:
    text = tok.decode("utf-8", "replace")
    return repr(text if len(text) <= 40 else text[:40] + "…")


def _fan(flat: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fan-triangulate polygons given as concatenated corner lists.

    Parameters
    ----------
    flat : (sum(counts),) int array
        the polygons' corners, one polygon after another.
    counts : (p,) int array
        corners per polygon, each ≥ 3.

    Returns
    -------
    F : (sum(counts - 2), 3) int64 array
        triangles (v0, vk, vk+1) for k = 1 … c-2.
    poly : (sum(counts - 2),) int64 array
        the polygon each triangle comes from.
    """
    counts = np.asarray(counts, dtype=np.int64)
    flat = np.asarray(flat, dtype=np.int64)
    if len(counts) and np.all(counts == 3):
        return flat.reshape(-1, 3), np.arange(len(counts), dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    ntri = counts - 2
    poly = np.repeat(np.arange(len(counts), dtype=np.int64), ntri)
    tri_start = np.concatenate([[0], np.cumsum(ntri)[:-1]])
    k = np.arange(len(poly), dtype=np.int64) - tri_start[poly] + 1
    first = starts[poly]
    F = np.column_stack([flat[first], flat[first + k], flat[first + k + 1]])
    return F, poly


def _check_range(F: np.ndarray, nv: int, where: Callable[[int], str]) -> None:
    """Raise ``bad_index`` for the first corner outside ``[0, nv)``; ``where(row)`` locates it."""
    bad = (F < 0) | (F >= nv)
    if bad.any():
        rows = np.flatnonzero(bad.any(axis=1))
        r = int(rows[0])
        value = int(F[r][bad[r]][0])
        more = f" ({len(rows)} faces have such indices)" if len(rows) > 1 else ""
        raise MeshError("bad_index", f"{where(r)}face refers to vertex {value}, but the file has "
                                     f"{nv} vertices{more}")


class _Rows:
    """A text body split into non-blank lines of whitespace-separated tokens, vectorized.

    Attributes
    ----------
    tokens : (t,) object array of bytes
    start, length, line : (r,) int64 arrays
        per non-blank line: index of its first token, its token count, its 1-based line number.
    """

    def __init__(self, body: bytes, first_line: int = 1) -> None:
        toks = np.array(_TOKEN_OR_NEWLINE.findall(body), dtype=object)
        if toks.size == 0:
            self.tokens = toks
            self.start = self.length = self.line = np.zeros(0, dtype=np.int64)
            return
        newline = toks == b"\n"
        line_of = np.cumsum(newline) - newline + first_line
        keep = ~newline
        self.tokens = toks[keep]
        tl = line_of[keep]
        if tl.size == 0:
            self.start = self.length = self.line = np.zeros(0, dtype=np.int64)
            return
        self.start = np.flatnonzero(np.concatenate([[True], tl[1:] != tl[:-1]])).astype(np.int64)
        self.length = np.diff(np.concatenate([self.start, [tl.size]])).astype(np.int64)
        self.line = tl[self.start].astype(np.int64)

    def __len__(self) -> int:
        return len(self.start)

    def column(self, rows: np.ndarray, col: int | np.ndarray) -> np.ndarray:
        """Tokens at position ``col`` of each row in ``rows`` (the caller checked the lengths)."""
        return self.tokens[self.start[rows] + col]


def _parse_float_block(rows: _Rows, sel: np.ndarray, cols: tuple[int, int, int], name: str,
                       what: str) -> np.ndarray:
    """(len(sel), 3) floats from the given columns of the selected rows."""
    need = max(cols) + 1
    short = np.flatnonzero(rows.length[sel] < need)
    if short.size:
        r = sel[short[0]]
        raise MeshError("unreadable", f"{name}: line {rows.line[r]}: {what} needs {need} numbers, "
                                      f"found {rows.length[r]}")
    idx = (rows.start[sel][:, None] + np.asarray(cols)[None, :]).ravel()
    toks = rows.tokens[idx]
    try:
        return _floats(toks).reshape(-1, 3)
    except (ValueError, OverflowError):
        bad = _first_bad(toks, float)
        r = sel[bad // 3]
        raise MeshError("unreadable", f"{name}: line {rows.line[r]}: {what} has a bad number "
                                      f"{_show(toks[bad])}") from None


# ---------------------------------------------------------------------------------------------
# OBJ
# ---------------------------------------------------------------------------------------------


def _parse_obj(data: bytes, name: str, max_faces: int | None) -> tuple[np.ndarray, np.ndarray]:
    if not data.strip():
        raise MeshError("empty", f"{name}: the file is empty")
    _decode_check(data, name)
    data = _strip_bom(data)
    if b"#" in data:
        data = _COMMENT.sub(b"", data)  # comments end at the line end: line numbers hold
    plain = _parse_plain_obj(data)
    if plain is not None:
        _check_max_faces(name, len(plain[1]), max_faces, "")
        return plain
    records = _OBJ_RECORD.findall(data)
    if not records:
        raise MeshError("empty", f"{name}: no vertex ('v') or face ('f') lines")
    rec = np.array(records, dtype=object).reshape(-1, 2)
    is_v = rec[:, 0] == b"v"
    V = _obj_vertices(data, rec[is_v, 1].tolist(), np.flatnonzero(is_v), name)
    f_rest = rec[~is_v, 1].tolist()
    if not f_rest:
        return V, np.zeros((0, 3), dtype=np.int64)
    return V, _obj_faces(data, f_rest, is_v, len(V), name, max_faces)


def vertex_lines(data: bytes, suffix: str) -> np.ndarray | None:
    """The file's 1-based line of each vertex of an OBJ file (its ``v`` lines, in order), for
    messages that name a vertex (error path only); None for the other formats, where vertices are
    not one a line (binary STL and PLY, OFF's free layout).

    Returns
    -------
    (n,) int64 array or None
    """
    if suffix.lower() != ".obj":
        return None
    text = _strip_bom(data)
    if b"#" in text:
        text = _COMMENT.sub(b"", text)      # as the parser reads it: line numbers hold
    starts = [m.start() for m in _OBJ_RECORD.finditer(text) if m.group(1) == b"v"]
    breaks = np.flatnonzero(np.frombuffer(text, dtype=np.uint8) == ord("\n"))
    return np.searchsorted(breaks, np.asarray(starts, dtype=np.int64)).astype(np.int64) + 1


def _obj_record_line(data: bytes, k: int) -> int:
    """The line of the k-th 'v' or 'f' record (error path only)."""
    for i, m in enumerate(_OBJ_RECORD.finditer(data)):
        if i == k:
            return _line_of(data, m.start())
    return 0


def _obj_vertices(data: bytes, v_rest: list[bytes], v_record: np.ndarray, name: str) -> np.ndarray:
    """The first three numbers of each 'v' line (w or colours after them are ignored)."""
    if not v_rest:
        return np.zeros((0, 3))
    triples = _XYZ_LINE.findall(b"\n".join(v_rest))
    if len(triples) != len(v_rest):
        bad = next((i for i, r in enumerate(v_rest) if not _XYZ_LINE.match(r)), 0)
        raise MeshError("unreadable", f"{name}: line {_obj_record_line(data, int(v_record[bad]))}: "
                                      f"a vertex needs 3 coordinates")
    toks = list(itertools.chain.from_iterable(triples))
    try:
        return _floats(toks).reshape(-1, 3)
    except (ValueError, OverflowError):
        bad = _first_bad(toks, float)
        line = _obj_record_line(data, int(v_record[bad // 3]))
        raise MeshError("unreadable", f"{name}: line {line}: bad vertex coordinate "
                                      f"{_show(toks[bad])}") from None


def _obj_faces(data: bytes, f_rest: list[bytes], is_v: np.ndarray, nv: int, name: str,
               max_faces: int | None) -> np.ndarray:
    """The 'f' lines fan-triangulated: corners 'i', 'i/j', 'i//k', 'i/j/k' → keep i."""
    f_record = np.flatnonzero(~is_v)
    # one newline token ends each face
    body = _OBJ_CORNER_TAIL.sub(b"", b"\n".join(f_rest) + b"\n")
    toks = np.array(_TOKEN_OR_NEWLINE.findall(body), dtype=object)
    newline = toks == b"\n"
    face_of = (np.cumsum(newline) - newline)[~newline]
    corners = toks[~newline]
    counts = np.bincount(face_of, minlength=len(f_rest))
    few = np.flatnonzero(counts < 3)
    if few.size:
        k = int(few[0])
        raise MeshError("unreadable", f"{name}: line {_obj_record_line(data, int(f_record[k]))}: a face needs "
                                      f"at least 3 corners, found {counts[k]}")
    _check_max_faces(name, int((counts - 2).sum()), max_faces, "")
    try:
        idx = _ints(corners)
    except (ValueError, OverflowError):
        bad = _first_bad(corners, int)
        line = _obj_record_line(data, int(f_record[face_of[bad]]))
        raise MeshError("unreadable", f"{name}: line {line}: bad face corner "
                                      f"{_show(corners[bad])} (expected a vertex number)") from None
    F, _ = _fan(_obj_vertex_indices(data, idx, face_of, is_v, nv, name), counts)
    return F


def _obj_vertex_indices(data: bytes, idx: np.ndarray, face_of: np.ndarray, is_v: np.ndarray, nv: int,
                        name: str) -> np.ndarray:
    """OBJ vertex numbers (from 1; negative: relative to the vertices before the face) as 0-based indices."""
    f_record = np.flatnonzero(~is_v)

    def line(corner: int) -> int:
        return _obj_record_line(data, int(f_record[face_of[corner]]))

    zero = np.flatnonzero(idx == 0)
    if zero.size:
        raise MeshError("bad_index", f"{name}: line {line(zero[0])}: face refers to vertex 0, but OBJ "
                                     f"vertex numbers start at 1")
    neg = idx < 0
    if neg.any():  # relative: -1 is the last vertex defined before this face's line
        v_before = np.cumsum(is_v)[f_record][face_of]
        resolved = np.where(neg, v_before + idx, idx - 1)
        badneg = np.flatnonzero(neg & (resolved < 0))
        if badneg.size:
            b = int(badneg[0])
            raise MeshError("bad_index", f"{name}: line {line(b)}: face refers to vertex {idx[b]} "
                                         f"(relative), but only {v_before[b]} vertices precede it")
        idx = resolved
    else:
        idx = idx - 1
    over = np.flatnonzero(idx >= nv)
    if over.size:
        b = int(over[0])
        raise MeshError("bad_index", f"{name}: line {line(b)}: face refers to vertex {idx[b] + 1}, "
                                     f"but the file has {nv} vertices")
    return idx


def _parse_plain_obj(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """The common file, in bulk: only ``v x y z`` and ``f a b c`` lines with positive vertex
    numbers that exist. None for anything else (quads, ``vn``/``vt``/``o`` lines, ``i/j/k``
    corners, relative or bad numbers): the general parser reads those and names the bad line.

    Every record has four tokens exactly when the tokens are four per record start and every fourth
    token is a record's ``v`` or ``f`` (a shorter or longer record shifts the ones after it onto
    numbers, which are never ``v`` or ``f``).
    """
    tokens = data.split()
    # records start a line with "v " or "f " (others: the general parser)
    starts = (data.count(b"\nv ") + data.count(b"\nf ") + (data[:2] in (b"v ", b"f ")))
    if not tokens or len(tokens) != 4 * starts:
        return None
    table = np.array(tokens).reshape(-1, 4)
    kind = table[:, 0]
    is_v = kind == b"v"
    if not np.all(is_v | (kind == b"f")):
        return None
    try:
        V = table[is_v, 1:].astype(np.float64)
        idx = table[~is_v, 1:].astype(np.int64)
    except (ValueError, OverflowError):
        return None
    if idx.size and (idx.min() < 1 or idx.max() > len(V)):
        return None
    return V, idx - 1


# ---------------------------------------------------------------------------------------------
# OFF
# ---------------------------------------------------------------------------------------------


def _parse_off(data: bytes, name: str, max_faces: int | None) -> tuple[np.ndarray, np.ndarray]:
    if not data.strip():
        raise MeshError("empty", f"{name}: the file is empty")
    _decode_check(data, name)
    rows = _Rows(_COMMENT.sub(b"", _strip_bom(data)))
    if len(rows) == 0:
        raise MeshError("empty", f"{name}: the file has no content")
    r = 0
    first = rows.tokens[rows.start[0]]
    if re.fullmatch(rb"[A-Za-z]*OFF", first):
        if first.upper() not in (b"OFF", b"COFF", b"NOFF", b"CNOFF", b"STOFF", b"STCOFF",
                                 b"STNOFF", b"STCNOFF", b"CSTOFF"):
            raise MeshError("unreadable", f"{name}: line {rows.line[0]}: unsupported OFF variant "
                                          f"{_show(first)}")
        if rows.length[0] > 1:  # "OFF nv nf ne" on one line
            count_toks = rows.tokens[rows.start[0] + 1: rows.start[0] + rows.length[0]].tolist()
            count_line = int(rows.line[0])
            r = 1
        else:
            if len(rows) < 2:
                raise MeshError("empty", f"{name}: the OFF header has no vertex and face counts")
            count_toks = rows.tokens[rows.start[1]: rows.start[1] + rows.length[1]].tolist()
            count_line = int(rows.line[1])
            r = 2
    elif re.fullmatch(rb"[0-9]+", first):  # the keyword is optional
        count_toks = rows.tokens[rows.start[0]: rows.start[0] + rows.length[0]].tolist()
        count_line = int(rows.line[0])
        r = 1
    else:
        raise MeshError("unreadable", f"{name}: line {rows.line[0]}: expected the 'OFF' header, "
                                      f"found {_show(first)}")
    try:
        nv, nf = (int(t) for t in count_toks[:2])
        if nv < 0 or nf < 0:
            raise ValueError
    except ValueError:
        raise MeshError("unreadable", f"{name}: line {count_line}: expected the vertex and face "
                                      f"counts, found {_show(b' '.join(count_toks))}") from None
    _check_max_faces(name, nf, max_faces, "the header declares ")
    if nv == 0:
        raise MeshError("empty", f"{name}: the file has no vertices")
    if nf == 0:
        raise MeshError("empty", f"{name}: the file has {nv} vertices but no faces")
    if len(rows) < r + nv + nf:
        have_v = min(nv, len(rows) - r)
        have_f = max(0, len(rows) - r - nv)
        raise MeshError("unreadable", f"{name}: the header (line {count_line}) declares {nv} "
                                      f"vertices and {nf} faces, but the file ends after "
                                      f"{have_v} vertices and {have_f} faces")
    vsel = np.arange(r, r + nv)
    V = _parse_float_block(rows, vsel, (0, 1, 2), name, "a vertex")
    fsel = np.arange(r + nv, r + nv + nf)
    count_tok = rows.column(fsel, 0)
    counts = _ints_or_error(count_tok, lambda bad: f"{name}: line {rows.line[fsel[bad]]}: expected "
                            f"a face's corner count, found {_show(count_tok[bad])}")
    few = np.flatnonzero(counts < 3)
    if few.size:
        k = int(few[0])
        raise MeshError("unreadable", f"{name}: line {rows.line[fsel[k]]}: a face needs at least "
                                      f"3 corners, found {counts[k]}")
    short = np.flatnonzero(rows.length[fsel] < counts + 1)
    if short.size:
        k = int(short[0])
        raise MeshError("unreadable", f"{name}: line {rows.line[fsel[k]]}: the face declares "
                                      f"{counts[k]} corners but lists {rows.length[fsel[k]] - 1}")
    _check_max_faces(name, int((counts - 2).sum()), max_faces, "")
    # Corner j of face i is token start + 1 + j; colour columns after them are ignored.
    poly = np.repeat(np.arange(nf), counts)
    offset = np.arange(len(poly)) - np.repeat(np.cumsum(counts) - counts, counts) + 1
    toks = rows.tokens[rows.start[fsel][poly] + offset]
    flat = _ints_or_error(toks, lambda bad: f"{name}: line {rows.line[fsel[poly[bad]]]}: bad face "
                          f"corner {_show(toks[bad])} (expected a vertex index)")
    F, tri_poly = _fan(flat, counts)
    _check_range(F, nv, lambda t: f"{name}: line {rows.line[fsel[tri_poly[t]]]}: ")
    return V, F


# ---------------------------------------------------------------------------------------------
# STL
# ---------------------------------------------------------------------------------------------

_STL_DTYPE = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _stl_is_binary(head: bytes, size: int) -> bool:
    if len(head) >= 84:
        n = int.from_bytes(head[80:84], "little")
        if size == 84 + 50 * n:
            return True
    return not head.lstrip().lower().startswith(b"solid")


def _precheck_stl(head: bytes, size: int, name: str, max_faces: int | None) -> None:
    if size == 0:
        raise MeshError("empty", f"{name}: the file is empty")
    if _stl_is_binary(head, size):
        if len(head) < 84:
            raise MeshError("unreadable", f"{name}: too short for a binary STL ({size} bytes, the "
                                          f"header alone is 84) and not an ASCII STL")
        n = int.from_bytes(head[80:84], "little")
        _check_max_faces(name, n, max_faces, "the binary STL header declares ")


def _parse_stl(data: bytes, name: str, max_faces: int | None) -> tuple[np.ndarray, np.ndarray]:
    if _stl_is_binary(data[:84], len(data)):
        n = int.from_bytes(data[80:84], "little")
        need = 84 + 50 * n
        if len(data) < need:
            whole = (len(data) - 84) // 50
            raise MeshError("unreadable", f"{name}: truncated binary STL: the header declares {n} "
                                          f"triangles ({need} bytes) but the file has {len(data)} "
                                          f"bytes (face {whole} is the first incomplete one)")
        if n == 0:
            raise MeshError("empty", f"{name}: the binary STL has no triangles")
        tri = np.frombuffer(data, dtype=_STL_DTYPE, count=n, offset=84)
        V = tri["v"].reshape(-1, 3).astype(np.float64)
        return V, np.arange(3 * n, dtype=np.int64).reshape(n, 3)
    _decode_check(data, name)
    triples = _STL_VERTEX.findall(data)
    if not triples:
        raise MeshError("empty", f"{name}: the ASCII STL has no triangles ('vertex' lines)")
    if len(triples) % 3:
        raise MeshError("unreadable", f"{name}: the ASCII STL has {len(triples)} 'vertex' lines, "
                                      f"not a multiple of 3: a facet is incomplete")
    n = len(triples) // 3
    _check_max_faces(name, n, max_faces, "")
    toks = list(itertools.chain.from_iterable(triples))
    try:
        V = _floats(toks).reshape(-1, 3)
    except (ValueError, OverflowError):
        bad = _first_bad(toks, float)
        m = next(itertools.islice(_STL_VERTEX.finditer(data), bad // 3, None))
        raise MeshError("unreadable", f"{name}: line {_line_of(data, m.start())}: bad vertex "
                                      f"coordinate {_show(toks[bad])}") from None
    return V, np.arange(3 * n, dtype=np.int64).reshape(n, 3)


# ---------------------------------------------------------------------------------------------
# PLY
# ---------------------------------------------------------------------------------------------


class _PlyProperty:
    __slots__ = ("name", "type", "count_type")

    def __init__(self, name: str, type_: str, count_type: str | None) -> None:
        self.name = name
        self.type = type_  # numpy code without byte order
        self.count_type = count_type  # None for scalars


class _PlyElement:
    __slots__ = ("name", "count", "props", "line")

    def __init__(self, name: str, count: int, line: int) -> None:
        self.name = name
        self.count = count
        self.props: list[_PlyProperty] = []
        self.line = line


def _ply_header(data: bytes, name: str) -> tuple[str, list[_PlyElement], int, int]:
    """Parse the header: (format, elements, body offset, header line count)."""
    if not data.startswith(b"ply"):
        if not data.strip():
            raise MeshError("empty", f"{name}: the file is empty")
        raise MeshError("unreadable", f"{name}: line 1: not a PLY file (it must start with 'ply')")
    end = _PLY_HEADER_END.search(data, 0, _PLY_HEADER_LIMIT + 64)
    if end is None:
        raise MeshError("unreadable", f"{name}: the PLY header has no 'end_header' line")
    try:
        header = data[:end.start()].decode("ascii")
    except UnicodeDecodeError as exc:
        raise MeshError("unreadable", f"{name}: line {_line_of(data, exc.start)}: the PLY header "
                                      f"is not ASCII text") from None
    fmt = None
    elements: list[_PlyElement] = []
    lines = header.split("\n")
    for lineno, raw in enumerate(lines, start=1):
        words = raw.split()
        if not words or words[0] in ("ply", "comment", "obj_info"):
            continue
        where = f"{name}: line {lineno}: "
        if words[0] == "format":
            if len(words) < 2 or words[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
                raise MeshError("unreadable", f"{where}unsupported PLY format {raw.strip()!r}")
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise MeshError("unreadable", f"{where}malformed element line {raw.strip()!r}")
            elements.append(_PlyElement(words[1], int(words[2]), lineno))
        elif words[0] == "property":
            if not elements:
                raise MeshError("unreadable", f"{where}property before any element")
            if len(words) == 5 and words[1] == "list":
                if words[2] not in _PLY_TYPES or words[3] not in _PLY_TYPES:
                    raise MeshError("unreadable", f"{where}unknown PLY type in {raw.strip()!r}")
                if _PLY_TYPES[words[2]][0] == "f":
                    raise MeshError("unreadable", f"{where}a list count must be an integer type")
                elements[-1].props.append(_PlyProperty(words[4], _PLY_TYPES[words[3]],
                                                       _PLY_TYPES[words[2]]))
            elif len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1].props.append(_PlyProperty(words[2], _PLY_TYPES[words[1]], None))
            else:
                raise MeshError("unreadable", f"{where}malformed property line {raw.strip()!r}")
        else:
            raise MeshError("unreadable", f"{where}unexpected PLY header line {raw.strip()!r}")
    if fmt is None:
        raise MeshError("unreadable", f"{name}: the PLY header has no 'format' line")
    return fmt, elements, end.end(), header.count("\n") + 2


def _ply_roles(elements: list[_PlyElement], name: str) -> tuple[_PlyElement, _PlyElement | None]:
    vert = next((e for e in elements if e.name == "vertex"), None)
    if vert is None:
        raise MeshError("empty", f"{name}: the PLY file has no 'vertex' element")
    names = [p.name for p in vert.props]
    for axis in ("x", "y", "z"):
        if axis not in names:
            raise MeshError("unreadable", f"{name}: the PLY vertex element has no '{axis}' property")
        if vert.props[names.index(axis)].count_type is not None:
            raise MeshError("unreadable", f"{name}: the PLY vertex property '{axis}' is a list")
    face = next((e for e in elements if e.name == "face"), None)
    if face is not None:
        if not any(p.name in ("vertex_indices", "vertex_index") and p.count_type for p in face.props):
            raise MeshError("unreadable", f"{name}: the PLY face element has no list property "
                                          f"'vertex_indices' or 'vertex_index'")
    return vert, face


def _face_prop(face: _PlyElement) -> int:
    return next(i for i, p in enumerate(face.props)
                if p.name in ("vertex_indices", "vertex_index") and p.count_type)


def _precheck_ply(head: bytes, name: str, max_faces: int | None) -> None:
    if max_faces is None or not head.startswith(b"ply") or not _PLY_HEADER_END.search(head):
        return  # the full parse reports what is wrong
    _, elements, _, _ = _ply_header(head, name)
    face = next((e for e in elements if e.name == "face"), None)
    if face is not None:
        # Every polygon gives at least one triangle: the declared count is a lower bound.
        _check_max_faces(name, face.count, max_faces, "the PLY header declares ")


def _parse_ply(data: bytes, name: str, max_faces: int | None) -> tuple[np.ndarray, np.ndarray]:
    fmt, elements, body_at, first_body_line = _ply_header(data, name)
    vert, face = _ply_roles(elements, name)
    if face is not None:
        _check_max_faces(name, face.count, max_faces, "the PLY header declares ")
    if vert.count == 0:
        raise MeshError("empty", f"{name}: the file has no vertices")
    if face is None or face.count == 0:
        raise MeshError("empty", f"{name}: the file has {vert.count} vertices but no faces")
    if fmt == "ascii":
        V, counts, flat, where = _ply_ascii_body(data, body_at, first_body_line, elements, vert,
                                                 face, name)
    else:
        V, counts, flat = _ply_binary_body(data, body_at, elements, vert, face,
                                           "<" if fmt == "binary_little_endian" else ">", name)

        def where(k: int) -> str:
            return f"{name}: face {k}: "
    few = np.flatnonzero(counts < 3)
    if few.size:
        k = int(few[0])
        raise MeshError("unreadable", f"{where(k)}a face needs at least 3 corners, found {counts[k]}")
    _check_max_faces(name, int((counts - 2).sum()), max_faces, "")
    F, tri_poly = _fan(flat, counts)
    _check_range(F, len(V), lambda t: where(int(tri_poly[t])))
    return V, F


def _ply_ascii_body(data: bytes, body_at: int, first_line: int, elements: list[_PlyElement],
                    vert: _PlyElement, face: _PlyElement, name: str
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, Callable[[int], str]]:
    """Vertices, polygon sizes, concatenated corners and a face locator (by line number)."""
    _decode_check(data, name, body_at)
    rows = _Rows(data[body_at:], first_line)
    r = 0
    V = counts = flat = None
    where = None
    for el in elements:
        if len(rows) < r + el.count:
            raise MeshError("unreadable", f"{name}: the header (line {el.line}) declares {el.count} "
                                          f"'{el.name}' records, but the file ends after "
                                          f"{max(0, len(rows) - r)}")
        sel = np.arange(r, r + el.count)
        if el is vert:
            names = [p.name for p in el.props]
            cols = tuple(names.index(a) for a in ("x", "y", "z"))
            if any(p.count_type for p in el.props[:max(cols)]):
                raise MeshError("unreadable", f"{name}: unsupported ASCII PLY layout: a list "
                                              f"property precedes the vertex coordinates")
            V = _parse_float_block(rows, sel, cols, name, "a vertex")
        elif el is face:
            p = _face_prop(el)
            if any(q.count_type for q in el.props[:p]):
                raise MeshError("unreadable", f"{name}: unsupported ASCII PLY layout: a list "
                                              f"property precedes the face's vertex indices")
            short = np.flatnonzero(rows.length[sel] < p + 1)
            if short.size:
                raise MeshError("unreadable", f"{name}: line {rows.line[sel[short[0]]]}: a face "
                                              f"record is missing its vertex list")
            count_tok = rows.column(sel, p)
            try:
                counts = _ints(count_tok)
            except (ValueError, OverflowError):
                bad = _first_bad(count_tok, int)
                raise MeshError("unreadable", f"{name}: line {rows.line[sel[bad]]}: expected a "
                                              f"corner count, found {_show(count_tok[bad])}") from None
            counts_ok = np.maximum(counts, 0)
            short = np.flatnonzero(rows.length[sel] < p + 1 + counts_ok)
            if short.size:
                k = int(short[0])
                raise MeshError("unreadable", f"{name}: line {rows.line[sel[k]]}: the face declares "
                                              f"{counts[k]} corners but lists "
                                              f"{rows.length[sel[k]] - p - 1}")
            poly = np.repeat(np.arange(el.count), counts_ok)
            offset = np.arange(len(poly)) - np.repeat(np.cumsum(counts_ok) - counts_ok, counts_ok)
            toks = rows.tokens[rows.start[sel][poly] + p + 1 + offset]
            try:
                flat = _ints(toks)
            except (ValueError, OverflowError):
                bad = _first_bad(toks, int)
                raise MeshError("unreadable", f"{name}: line {rows.line[sel[poly[bad]]]}: bad face "
                                              f"corner {_show(toks[bad])}") from None
            face_lines = rows.line[sel]

            def where(k: int, _lines=face_lines) -> str:
                return f"{name}: line {_lines[k]}: "
        r += el.count
    return V, counts, flat, where


def _ply_binary_element(data: bytes, off: int, el: _PlyElement, bo: str, name: str
                        ) -> tuple[list, int]:
    """Read one element's records from ``data[off:]``.

    Returns
    -------
    fields : list
        per property: an (count,) array for scalars, or (counts, flat) for lists.
    off : int
        the offset just after the element.
    """
    if not el.props or el.count == 0:
        return [None] * len(el.props), off
    if not any(p.count_type for p in el.props):
        return _ply_scalar_records(data, off, el, bo, name)
    uniform = _ply_uniform_records(data, off, el, bo, name)
    if uniform is not None:
        return uniform
    return _ply_mixed_records(data, off, el, bo, name)


def _ply_truncated(name: str, el: _PlyElement, done: int) -> MeshError:
    return MeshError("unreadable", f"{name}: truncated PLY: the header (line {el.line}) declares "
                                   f"{el.count} '{el.name}' records but the file ends within "
                                   f"record {done}")


def _ply_scalar_records(data: bytes, off: int, el: _PlyElement, bo: str, name: str) -> tuple[list, int]:
    """An element without lists: one structured dtype."""
    dt = np.dtype([(f"p{i}", bo + p.type) for i, p in enumerate(el.props)])
    if off + el.count * dt.itemsize > len(data):
        raise _ply_truncated(name, el, (len(data) - off) // dt.itemsize)
    rec = np.frombuffer(data, dtype=dt, count=el.count, offset=off)
    return [rec[f"p{i}"] for i in range(len(el.props))], off + el.count * dt.itemsize


def _ply_first_list_lengths(data: bytes, off: int, el: _PlyElement, bo: str, name: str) -> list[int]:
    """The list lengths of the element's first record."""
    first: list[int] = []
    pos = off
    try:
        for p in el.props:
            if p.count_type is None:
                pos += np.dtype(p.type).itemsize
            else:
                c = int(np.frombuffer(data, dtype=bo + p.count_type, count=1, offset=pos)[0])
                first.append(c)
                pos += np.dtype(p.count_type).itemsize + max(c, 0) * np.dtype(p.type).itemsize
    except ValueError:
        raise _ply_truncated(name, el, 0) from None
    if pos > len(data):
        raise _ply_truncated(name, el, 0)
    return first


def _ply_uniform_records(data: bytes, off: int, el: _PlyElement, bo: str, name: str
                         ) -> tuple[list, int] | None:
    """Lists, assuming every record has the first record's list lengths (the common case: all
    triangles), read with one structured dtype and verified; None when they differ."""
    first = _ply_first_list_lengths(data, off, el, bo, name)
    if not all(c >= 0 for c in first):
        return None
    fields_dt = []
    it = iter(first)
    for i, p in enumerate(el.props):
        if p.count_type is None:
            fields_dt.append((f"p{i}", bo + p.type))
        else:
            fields_dt.append((f"c{i}", bo + p.count_type))
            fields_dt.append((f"p{i}", bo + p.type, (next(it),)))
    dt = np.dtype(fields_dt)
    if off + el.count * dt.itemsize > len(data):
        return None
    rec = np.frombuffer(data, dtype=dt, count=el.count, offset=off)
    uniform = all(np.all(rec[f"c{i}"] == rec[f"c{i}"][0])
                  for i, p in enumerate(el.props) if p.count_type)
    if not uniform:
        return None
    out = []
    for i, p in enumerate(el.props):
        if p.count_type is None:
            out.append(rec[f"p{i}"])
        else:
            counts = rec[f"c{i}"].astype(np.int64)
            out.append((counts, rec[f"p{i}"].reshape(-1)))
    return out, off + el.count * dt.itemsize


def _ply_mixed_records(data: bytes, off: int, el: _PlyElement, bo: str, name: str) -> tuple[list, int]:
    """Mixed list lengths: one pass over the records to find the lists, then gather in bulk."""
    layout = []
    for p in el.props:
        if p.count_type is None:
            layout.append((None, np.dtype(p.type).itemsize, 0))
        else:
            cfmt = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I"}[p.count_type]
            layout.append((struct.Struct(bo + cfmt), np.dtype(p.count_type).itemsize,
                           np.dtype(p.type).itemsize))
    nprops = len(el.props)
    starts: list[list[int]] = [[] for _ in range(nprops)]
    counts_l: list[list[int]] = [[] for _ in range(nprops)]
    size = len(data)
    pos = off
    for k in range(el.count):
        for i, (cs, csize, isize) in enumerate(layout):
            if cs is None:
                starts[i].append(pos)
                pos += csize
            else:
                if pos + csize > size:
                    raise _ply_truncated(name, el, k)
                c = cs.unpack_from(data, pos)[0]
                if c < 0:
                    raise MeshError("unreadable", f"{name}: '{el.name}' record {k} has a negative "
                                                  f"list length {c}")
                pos += csize
                starts[i].append(pos)
                counts_l[i].append(c)
                pos += c * isize
        if pos > size:
            raise _ply_truncated(name, el, k)
    return _ply_gather(data, el, bo, starts, counts_l), pos


def _ply_gather(data: bytes, el: _PlyElement, bo: str, starts: list[list[int]], counts_l: list[list[int]]
                ) -> list:
    """Each property's values from where the records hold them (byte offsets, list lengths)."""
    raw = np.frombuffer(data, dtype=np.uint8)
    out = []
    for i, p in enumerate(el.props):
        isize = np.dtype(p.type).itemsize
        st = np.asarray(starts[i], dtype=np.int64)
        if p.count_type is None:
            byte_idx = st[:, None] + np.arange(isize)
            out.append(raw[byte_idx].view(bo + p.type).reshape(-1))
        else:
            counts = np.asarray(counts_l[i], dtype=np.int64)
            item = np.repeat(st, counts) + isize * (
                np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts))
            byte_idx = item[:, None] + np.arange(isize)
            out.append((counts, raw[byte_idx].view(bo + p.type).reshape(-1)))
    return out


def _ply_binary_body(data: bytes, off: int, elements: list[_PlyElement], vert: _PlyElement,
                     face: _PlyElement, bo: str, name: str
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices, polygon sizes and concatenated corners; trailing elements are not read."""
    V = counts = flat = None
    for el in elements:
        fields, off = _ply_binary_element(data, off, el, bo, name)
        if el is vert:
            names = [p.name for p in el.props]
            V = np.column_stack([fields[names.index(a)].astype(np.float64) for a in ("x", "y", "z")])
        elif el is face:
            counts, flat = fields[_face_prop(el)]
            flat = flat.astype(np.int64)
            if np.any(counts < 0):
                k = int(np.flatnonzero(counts < 0)[0])
                raise MeshError("unreadable", f"{name}: face {k}: negative corner count {counts[k]}")
        if el is vert or el is face:
            if V is not None and counts is not None:
                break  # trailing elements are not needed
    return V, counts, flat
