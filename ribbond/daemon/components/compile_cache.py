"""The compile cache: a design compiled once is served again at once for the same inputs.

An entry is addressed by the SHA-256 of everything a compile reads (``cache_key``): the mesh's bytes
and file name (``design.json`` names the source file), the canonical parameters with the daemon's
settings that reach the worker, the daemon's curvature tables and the printer profile's content,
and the engine's identity (``engine_identity``: its source and data files and the versions of the
numeric libraries it runs on, hashed once at start), so a changed engine never serves an older design.

An entry is a folder ``<cache_dir>/<key>/`` holding ``design/``, ``plans/`` and ``manifest.json``
(each file's SHA-256 and the worker's events). It is written in a temporary folder and renamed into
place, so it appears whole or not at all; two daemons (or test workers) storing the same key at once
both succeed, the second rename finds the first's entry and drops its own. A hit checks every file
against the manifest while copying it into the job, so a damaged entry (a file cut short, the disk
after a power cut) is never served: it is removed and the job compiles.
"""

from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import secrets
import shutil
import time
from importlib import metadata
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

#: The engine's rooms (``docs/architecture.md``): what a compile runs, hashed into its identity
#: (``printer`` too: the G-code stage's checker uses its codec).
ENGINE_ROOMS = ("mesh", "design", "deploy", "gcode", "pipeline", "calibration", "panels", "printer")
#: Modules of the package root the engine imports.
ENGINE_ROOT_FILES = ("datafiles.py",)
#: Libraries whose version can change a compile's bytes (solvers, geometry, the PNG writer).
ENGINE_LIBRARIES = ("numpy", "scipy", "libigl", "shapely", "matplotlib", "cholespy", "cvxopt", "pydantic")
#: What an entry holds besides its manifest.
ENTRY_FOLDERS = ("design", "plans")
MANIFEST = "manifest.json"
#: A temporary folder older than this was left by a process that died while storing.
LEFTOVER_AGE_S = 3600.0
FORMAT = 1


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def engine_identity(package: Path | None = None) -> str:
    """SHA-256 (hex) of the engine: every file of ``ENGINE_ROOMS`` under ``package`` (the installed
    ``ribbond`` by default; sources and data files, compiled caches left out) with its relative path,
    ``ENGINE_ROOT_FILES``, and the installed versions of ``ENGINE_LIBRARIES``."""
    package = package or Path(__file__).resolve().parents[2]
    h = hashlib.sha256(f"ribbond compile cache {FORMAT}\n".encode())
    files = [package / name for name in ENGINE_ROOT_FILES]
    for room in ENGINE_ROOMS:
        files += sorted(p for p in (package / room).rglob("*")
                        if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc")
    for path in files:
        h.update(f"{path.relative_to(package).as_posix()}\0{_file_digest(path)}\n".encode())
    for name in ENGINE_LIBRARIES:
        try:
            version = metadata.version(name)
        except metadata.PackageNotFoundError:
            version = "absent"                        # e.g. cholespy on aarch64: SuperLU's bits instead
        h.update(f"{name}=={version}\n".encode())
    return h.hexdigest()


def cache_key(mesh: Path, parameters: dict[str, Any], tables_dir: Path | None, profile: Path | None,
              engine: str) -> str:
    """SHA-256 (hex) of one compile's inputs.

    Parameters
    ----------
    mesh
        the uploaded mesh: its bytes and its file name (``design.json`` records the name).
    parameters
        everything else the worker is given (design parameters, the daemon's settings), JSON-able;
        canonicalized (sorted keys), so the order a client wrote them in does not matter.
    tables_dir
        the daemon's curvature tables (every ``*.toml``, by name and content), or None.
    profile
        the printer profile's file, or None.
    engine
        ``engine_identity()``.
    """
    h = hashlib.sha256(f"engine {engine}\n".encode())
    h.update(f"mesh {mesh.name}\0{_file_digest(mesh)}\n".encode())
    canonical = json.dumps(parameters, sort_keys=True, separators=(",", ":"), allow_nan=False)
    h.update(f"parameters {hashlib.sha256(canonical.encode()).hexdigest()}\n".encode())
    tables = sorted(tables_dir.glob("*.toml")) if tables_dir is not None and tables_dir.is_dir() else []
    for table in tables:
        h.update(f"table {table.name}\0{_file_digest(table)}\n".encode())
    if profile is not None:
        h.update(f"profile {_file_digest(profile)}\n".encode())
    return h.hexdigest()


def _swap_paths(value: Any, old: str, new: str) -> Any:
    """``value`` (JSON-like) with ``old`` replaced by ``new`` in every string (the job's folder)."""
    if isinstance(value, str):
        return value.replace(old, new)
    if isinstance(value, list):
        return [_swap_paths(v, old, new) for v in value]
    if isinstance(value, dict):
        return {k: _swap_paths(v, old, new) for k, v in value.items()}
    return value


class CompileCache:
    """The cache in ``directory`` for the engine ``engine`` (``engine_identity()``)."""

    def __init__(self, directory: Path, engine: str) -> None:
        self.directory, self.engine = Path(directory), engine
        self.directory.mkdir(parents=True, exist_ok=True)
        if not os.access(self.directory, os.W_OK | os.X_OK):     # a cache that could never store
            raise PermissionError(errno.EACCES, "not writable", str(self.directory))
        self._prune_leftovers()

    def key(self, mesh: Path, parameters: dict[str, Any], tables_dir: Path | None, profile: Path | None) -> str:
        """``cache_key`` with this cache's engine."""
        return cache_key(mesh, parameters, tables_dir, profile, self.engine)

    def _prune_leftovers(self) -> None:
        """Temporary folders of stores that died part way (old enough that none is still being written)."""
        now = time.time()
        for path in self.directory.glob(".*"):
            try:
                if path.is_dir() and now - path.stat().st_mtime > LEFTOVER_AGE_S:
                    shutil.rmtree(path, ignore_errors=True)
            except OSError:
                continue

    def _temporary(self, key: str) -> Path:
        return self.directory / f".tmp-{key[:16]}-{os.getpid()}-{secrets.token_hex(4)}"

    def store(self, key: str, job_folder: Path, events: list[dict[str, Any]]) -> bool:
        """Keep the job's compiled ``design/`` and ``plans/`` (and the worker's ``events``) under ``key``.

        Whether this call wrote the entry (False: it was there already, or the disk refused; the
        job is not affected either way)."""
        final = self.directory / key
        if final.exists():
            return False
        tmp = self._temporary(key)
        try:
            files: dict[str, str] = {}
            for name in ENTRY_FOLDERS:
                shutil.copytree(job_folder / name, tmp / name)
                files.update({p.relative_to(tmp).as_posix(): _file_digest(p)
                              for p in sorted((tmp / name).rglob("*")) if p.is_file()})
            events = _swap_paths(events, str(job_folder), "{job}")
            (tmp / MANIFEST).write_text(json.dumps({"format": FORMAT, "key": key, "files": files,
                                                    "events": events}), encoding="utf-8")
            os.rename(tmp, final)                     # atomic: the entry appears whole or not at all
            return True
        except OSError as exc:
            if not final.exists():
                log.warning("compile cache: cannot store %s: %s", key[:16], exc)
            return False
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def serve(self, key: str, job_folder: Path) -> list[dict[str, Any]] | None:
        """The entry ``key`` copied into ``job_folder`` (``design/``, ``plans/``), each file checked
        against the manifest on the way; the compile's events for this job. None on a miss, and for
        a damaged entry (removed, so that the compile that follows stores it afresh)."""
        entry = self.directory / key
        if not entry.is_dir():
            return None
        if any((job_folder / name).exists() for name in ENTRY_FOLDERS):
            return None                               # not a fresh job: compile it as it is
        staging = job_folder / f".cache-{secrets.token_hex(4)}"
        try:
            try:
                events = self._copy_checked(entry, key, staging)
            except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
                log.warning("compile cache: entry %s is damaged (%s): removed, compiling", key[:16], exc)
                self._discard(entry)
                return None
            try:
                for name in ENTRY_FOLDERS:
                    os.rename(staging / name, job_folder / name)
            except OSError as exc:
                log.warning("compile cache: cannot serve %s into %s (%s): compiling", key[:16], job_folder, exc)
                for name in ENTRY_FOLDERS:            # nothing half-served stays in the job
                    shutil.rmtree(job_folder / name, ignore_errors=True)
                return None
        finally:
            shutil.rmtree(staging, ignore_errors=True)
        return _swap_paths(events, "{job}", str(job_folder))

    def _copy_checked(self, entry: Path, key: str, staging: Path) -> list[dict[str, Any]]:
        """Copy the entry's files to ``staging``, each read once and checked against the manifest;
        the manifest's events. ValueError for a damaged entry."""
        manifest = json.loads((entry / MANIFEST).read_text(encoding="utf-8"))
        files = manifest["files"]
        if manifest.get("format") != FORMAT or manifest.get("key") != key or not isinstance(files, dict):
            raise ValueError("its manifest is not this entry's")
        for name in ENTRY_FOLDERS:
            (staging / name).mkdir(parents=True)
        for relative, digest in files.items():
            if relative.split("/")[0] not in ENTRY_FOLDERS or ".." in relative.split("/"):
                raise ValueError(f"the manifest names {relative!r}")
            data = (entry / relative).read_bytes()
            if hashlib.sha256(data).hexdigest() != digest:
                raise ValueError(f"{relative} does not match its SHA-256")
            (staging / relative).parent.mkdir(parents=True, exist_ok=True)
            (staging / relative).write_bytes(data)
        events = manifest["events"]
        if not isinstance(events, list) or not events or events[-1].get("event") != "done":
            raise ValueError("its events do not end with the compile's end")
        return events

    def _discard(self, entry: Path) -> None:
        """Take a damaged entry out of the way at once (a rename), then delete it."""
        doomed = self.directory / f".bad-{secrets.token_hex(6)}"
        try:
            os.rename(entry, doomed)
        except OSError:
            return                                    # another process removed it first
        shutil.rmtree(doomed, ignore_errors=True)
