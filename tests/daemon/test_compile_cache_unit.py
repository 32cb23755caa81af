"""The compile cache on its own (``ribbond.daemon.components.compile_cache``): the key is the
compile's inputs and nothing else, an entry is served byte for byte, a damaged entry never is.

The daemon's use of it (a resubmitted mesh served, the same events) is ``test_compile_cache.py``.
"""

from __future__ import annotations

import asyncio
import json
import os
import threading
from pathlib import Path

import pytest

from ribbond.daemon.components.compile_cache import (
    ENGINE_ROOMS, MANIFEST, CompileCache, cache_key, engine_identity)
from ribbond.daemon.config import DaemonConfig, load_config

PARAMS = {"parameters": {"size": {"bbox_diagonal": 70}, "printer_profile": "ultimaker2-tpu"},
          "max_faces": 200000, "predict": False, "optimize": True}
ENGINE = "e" * 64


def job_folder(root: Path, name: str = "job") -> Path:
    """A job folder as a finished compile leaves it: ``design/`` (with the folder's own path in
    nothing), ``plans/``, and the events the worker printed."""
    folder = root / name
    (folder / "design").mkdir(parents=True)
    (folder / "plans").mkdir()
    (folder / "design" / "front.gcode").write_bytes(b"G28\nG1 X10 Y10 E0.5\n")
    (folder / "design" / "back.gcode").write_bytes(b"G28\nG1 X20 Y20 E0.7\n")
    (folder / "design" / "preview.png").write_bytes(bytes(range(256)) * 40)
    (folder / "plans" / "front-plan.npz").write_bytes(os.urandom(3000))
    return folder


def events_of(folder: Path) -> list[dict[str, object]]:
    return [{"event": "stage", "stage": "load", "description": "reading mesh.obj"},
            {"event": "finished", "stage": "write", "seconds": 0.1, "summary": str(folder / "design")},
            {"event": "done", "design_dir": str(folder / "design"), "ribbons": {"front": 2, "back": 17},
             "report": {"ribbons": 19}}]


def files_of(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def mesh(tmp_path: Path) -> Path:
    path = tmp_path / "saddle.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0.1\nf 1 2 3\n", encoding="ascii")
    return path


@pytest.fixture
def tables(tmp_path: Path) -> Path:
    folder = tmp_path / "tables"
    folder.mkdir()
    (folder / "lycra-a.toml").write_text('name = "lycra-a"\nprestretch = 1.3\n', encoding="utf-8")
    return folder


def test_the_key_changes_with_every_input_and_only_with_them(tmp_path: Path, mesh: Path, tables: Path) -> None:
    profile = tmp_path / "profile.toml"
    profile.write_text('name = "p"\n', encoding="utf-8")
    base = cache_key(mesh, PARAMS, tables, profile, ENGINE)
    # the same inputs, written in another order: the same key
    reordered = {k: PARAMS[k] for k in reversed(list(PARAMS))}
    assert cache_key(mesh, reordered, tables, profile, ENGINE) == base
    keys = {"base": base}
    keys["parameter"] = cache_key(mesh, {**PARAMS, "predict": True}, tables, profile, ENGINE)
    keys["size"] = cache_key(mesh, {**PARAMS, "parameters": {**PARAMS["parameters"], "size": {"bbox_diagonal": 71}}},
                             tables, profile, ENGINE)
    keys["engine"] = cache_key(mesh, PARAMS, tables, profile, "f" * 64)
    other = tmp_path / "other"
    other.mkdir()
    renamed = other / "hyperbolic.obj"                 # design.json names the source file
    renamed.write_bytes(mesh.read_bytes())
    keys["name"] = cache_key(renamed, PARAMS, tables, profile, ENGINE)
    mesh.write_bytes(mesh.read_bytes() + b"\n")        # one byte more: another mesh file
    keys["mesh byte"] = cache_key(mesh, PARAMS, tables, profile, ENGINE)
    (tables / "lycra-a.toml").write_text('name = "lycra-a"\nprestretch = 1.4\n', encoding="utf-8")
    keys["table"] = cache_key(mesh, PARAMS, tables, profile, ENGINE)
    (tables / "lycra-b.toml").write_text('name = "lycra-b"\nprestretch = 1.4\n', encoding="utf-8")
    keys["new table"] = cache_key(mesh, PARAMS, tables, profile, ENGINE)
    profile.write_text('name = "q"\n', encoding="utf-8")
    keys["profile"] = cache_key(mesh, PARAMS, tables, profile, ENGINE)
    assert len(set(keys.values())) == len(keys), keys


def test_the_engine_identity_follows_its_files(tmp_path: Path) -> None:
    """Any source or data file of the engine's rooms changes it; a compiled cache does not."""
    package = tmp_path / "ribbond"
    for room in ENGINE_ROOMS:
        (package / room).mkdir(parents=True)
        (package / room / "__init__.py").write_text(f"# {room}\n", encoding="utf-8")
    (package / "datafiles.py").write_text("# shared\n", encoding="utf-8")
    (package / "gcode" / "profiles").mkdir()
    profile = package / "gcode" / "profiles" / "p.toml"
    profile.write_text("speed = 1\n", encoding="utf-8")
    first = engine_identity(package)
    assert engine_identity(package) == first
    (package / "design" / "__pycache__").mkdir()
    (package / "design" / "__pycache__" / "x.cpython-311.pyc").write_bytes(b"\0")
    assert engine_identity(package) == first
    (package / "daemon").mkdir()                      # not the engine: the daemon serves, it does not compile
    (package / "daemon" / "x.py").write_text("y = 1\n", encoding="utf-8")
    assert engine_identity(package) == first
    profile.write_text("speed = 2\n", encoding="utf-8")
    second = engine_identity(package)
    (package / "deploy" / "solver.py").write_text("z = 1\n", encoding="utf-8")
    third = engine_identity(package)
    assert len({first, second, third}) == 3
    assert engine_identity() == engine_identity()     # the installed one: the same on every call


def test_a_stored_design_is_served_byte_for_byte_with_the_jobs_own_paths(tmp_path: Path) -> None:
    cache = CompileCache(tmp_path / "cache", ENGINE)
    first = job_folder(tmp_path, "job-1")
    assert cache.serve("a" * 64, tmp_path) is None    # nothing stored yet: a miss
    assert cache.store("a" * 64, first, events_of(first))
    assert not cache.store("a" * 64, first, events_of(first))    # there already
    second = tmp_path / "job-2"
    second.mkdir()
    events = cache.serve("a" * 64, second)
    assert events == events_of(second)               # the compile's events, this job's paths
    assert files_of(second) == files_of(first)
    assert sorted(p.name for p in second.iterdir()) == ["design", "plans"]    # no staging left
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["a" * 64]


@pytest.mark.parametrize("damage", ["truncated file", "missing file", "missing manifest", "manifest cut",
                                    "other key's manifest", "events without the end"])
def test_a_damaged_entry_is_never_served_and_is_removed(tmp_path: Path, damage: str) -> None:
    cache = CompileCache(tmp_path / "cache", ENGINE)
    first = job_folder(tmp_path, "job-1")
    key = "b" * 64
    assert cache.store(key, first, events_of(first))
    entry = tmp_path / "cache" / key
    manifest = entry / MANIFEST
    if damage == "truncated file":
        gcode = entry / "design" / "back.gcode"
        gcode.write_bytes(gcode.read_bytes()[:-3])
    elif damage == "missing file":
        (entry / "plans" / "front-plan.npz").unlink()
    elif damage == "missing manifest":               # as a folder left by a store that died
        manifest.unlink()
    elif damage == "manifest cut":
        manifest.write_text(manifest.read_text(encoding="utf-8")[:40], encoding="utf-8")
    elif damage == "other key's manifest":
        data = json.loads(manifest.read_text(encoding="utf-8"))
        manifest.write_text(json.dumps({**data, "key": "c" * 64}), encoding="utf-8")
    else:
        data = json.loads(manifest.read_text(encoding="utf-8"))
        manifest.write_text(json.dumps({**data, "events": data["events"][:-1]}), encoding="utf-8")
    second = tmp_path / "job-2"
    second.mkdir()
    assert cache.serve(key, second) is None
    assert list(second.iterdir()) == []              # nothing of it reached the job
    assert not entry.exists()                        # removed: the compile that follows stores it again
    assert cache.store(key, first, events_of(first))
    assert cache.serve(key, second) == events_of(second)


def test_a_job_with_a_design_already_is_not_served_into(tmp_path: Path) -> None:
    cache = CompileCache(tmp_path / "cache", ENGINE)
    first = job_folder(tmp_path, "job-1")
    cache.store("d" * 64, first, events_of(first))
    other = job_folder(tmp_path, "job-2")
    other_design = other / "design" / "front.gcode"
    other_design.write_bytes(b"; its own\n")
    before = files_of(other)
    assert cache.serve("d" * 64, other) is None
    assert files_of(other) == before
    assert (tmp_path / "cache" / ("d" * 64)).is_dir()  # the entry is sound: kept


def test_two_processes_storing_one_key_at_once_both_succeed(tmp_path: Path) -> None:
    """Two daemons (or test workers) sharing a cache: the rename makes one entry, whole."""
    caches = [CompileCache(tmp_path / "cache", ENGINE) for _ in range(2)]
    folders = [job_folder(tmp_path, f"job-{i}") for i in range(2)]
    for name, data in files_of(folders[0]).items():   # the same compile's bytes in both
        (folders[1] / name).write_bytes(data)
    start = threading.Barrier(2)
    stored: list[bool] = []

    def store(i: int) -> None:
        start.wait()
        for _ in range(20):
            stored.append(caches[i].store("e" * 64, folders[i], events_of(folders[i])))

    threads = [threading.Thread(target=store, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert stored.count(True) == 1
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["e" * 64]    # no temporary left
    served = tmp_path / "job-3"
    served.mkdir()
    assert caches[1].serve("e" * 64, served) is not None
    assert files_of(served) == files_of(folders[0])


def test_leftovers_of_a_store_that_died_are_removed_at_start(tmp_path: Path) -> None:
    folder = tmp_path / "cache"
    old, fresh = folder / ".tmp-old-1-x", folder / ".tmp-new-2-y"
    for path in (old, fresh):
        (path / "design").mkdir(parents=True)
    os.utime(old, (0, 0))
    CompileCache(folder, ENGINE)
    assert not old.exists()
    assert fresh.exists()                             # perhaps another daemon's store, under way


def test_the_setting_default_off_and_relative(tmp_path: Path) -> None:
    assert DaemonConfig(state_dir=tmp_path).compile_cache_dir == tmp_path / "compile-cache"
    config = tmp_path / "etc" / "ribbond.toml"
    config.parent.mkdir()
    config.write_text('state_dir = "state"\n[design]\ncache_dir = ""\n', encoding="utf-8")
    assert load_config(config, environ={}).compile_cache_dir is None
    config.write_text('state_dir = "state"\n[design]\ncache_dir = "cache"\n', encoding="utf-8")
    assert load_config(config, environ={}).compile_cache_dir == tmp_path / "etc" / "cache"
    config.write_text('[design]\ncache_dir = "  "\n', encoding="utf-8")
    with pytest.raises(ValueError, match=r"design\.cache_dir: .*blank"):
        load_config(config, environ={})


def test_a_cache_folder_the_daemon_cannot_make_stops_it_naming_the_setting(tmp_path: Path) -> None:
    import subprocess
    import sys

    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder\n", encoding="utf-8")
    config = tmp_path / "ribbond.toml"
    config.write_text(f'state_dir = "{tmp_path / "state"}"\n[serial]\nport = "{tmp_path / "none"}"\n'
                      f'[api]\nport = 0\n[design]\ncache_dir = "{blocker / "cache"}"\n', encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "ribbond", "--config", str(config)], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "[design] cache_dir" in proc.stderr and str(blocker / "cache") in proc.stderr


class _CancellingCache:
    """A cache whose hit takes long enough for the operator to cancel the job while it is copied."""

    directory = Path("cache")

    def __init__(self, records: object, events: list[dict[str, object]]) -> None:
        self.records, self.events, self.stored = records, events, False
        self.loop = asyncio.get_running_loop()

    def key(self, *args: object) -> str:
        return "k" * 64

    def serve(self, key: str, folder: Path) -> list[dict[str, object]]:
        """(In the compiler's worker thread) the operator's cancel lands on the event loop meanwhile."""
        from ribbond.daemon.jobs import JobState
        cancelled = threading.Event()

        def cancel() -> None:
            self.records.transition(folder.name, JobState.CANCELLED)   # type: ignore[attr-defined]
            cancelled.set()
        self.loop.call_soon_threadsafe(cancel)
        assert cancelled.wait(10)
        return self.events

    def store(self, *args: object) -> None:
        self.stored = True


async def test_a_job_cancelled_while_its_cached_design_is_copied_gets_no_stage_after_its_cancel(
        tmp_path: Path) -> None:
    from ribbond.daemon.components.compiler import Compiler
    from ribbond.daemon.events import EventBus
    from ribbond.daemon.jobs import JobState
    from ribbond.daemon.records import JobRecords
    from ribbond.daemon.store import JobStore
    store, bus = JobStore(tmp_path / "jobs.db"), EventBus()
    published = bus.subscribe()
    records = JobRecords(store, bus, tmp_path / "jobs", 10, lambda job: {"state": job.state.value, "stage": job.stage})
    job = store.create(mesh_name="m.obj", mesh_path=str(tmp_path / "m.obj"), parameters={}, start_when_ready=False)
    (tmp_path / "m.obj").write_text("v 0 0 0\n", encoding="utf-8")
    records.dir(job.id).mkdir(parents=True)
    compiler = Compiler(DaemonConfig(state_dir=tmp_path, design={"cache_dir": ""}), records, tmp_path, lambda _: None,
                        "python")
    later_stage = {"event": "stage", "stage": "flatten", "description": "flattening"}   # not the first stage
    compiler.cache = _CancellingCache(records, [later_stage, *events_of(records.dir(job.id))])  # type: ignore[assignment]
    await compiler._compile(job.id)
    seen = []
    while not published.empty():
        seen.append(published.get_nowait()["job"])
    assert seen == [{"state": "compiling", "stage": "load"}, {"state": "cancelled", "stage": "load"}], seen
    assert store.get(job.id).state is JobState.CANCELLED and not compiler.cache.stored
