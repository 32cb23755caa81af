"""The daemon's compile cache end to end (``[design] cache_dir``): a real ``ribbond`` with a cache
folder of its own (not the session's), jobs submitted over HTTP, the events read as the dashboard
reads them (``GET /events``).

What the protocol says: a mesh submitted again with the same parameters is served (its
``compile.log`` says so) with the same design folder, byte for byte, and the same stage events; a
changed parameter, mesh byte or curvature table is compiled afresh; a damaged entry is compiled
afresh, never served. The cache on its own: ``test_compile_cache_unit.py``.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.design.surfaces import saddle
from ribbond.design.thickness import TABLE_DIR
from ribbond.mesh.files import write_obj
from tests.daemon.conftest import Daemon, submit, wait_for

SERVED = "served from the compile cache"
#: A small saddle designed as it is (not refined at intake): a compile of a few seconds, so that
#: the misses below cost little; what is cached does not depend on the mesh's size.
SMALL = {"size": {"bbox_diagonal": 70}, "solver": {"refine_below_faces": 0}}


class EventLog:
    """``GET /events`` read in a thread: each job's stages in the order the daemon published them."""

    def __init__(self, url: str) -> None:
        self.events: list[dict[str, Any]] = []
        self._client = httpx.Client(base_url=url, timeout=None)
        self._open = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()
        assert self._open.wait(30), "the event stream did not open"

    def _read(self) -> None:
        try:
            with self._client.stream("GET", "/events") as response:
                for line in response.iter_lines():
                    self._open.set()
                    if line.startswith("data: "):
                        self.events.append(json.loads(line[len("data: "):]))
        except (httpx.HTTPError, RuntimeError, ValueError):
            return                                    # closed by stop()

    def stages(self, job: str) -> list[str | None]:
        seen = [e["job"]["stage"] for e in list(self.events) if e.get("type") == "job" and e["job"]["id"] == job]
        return [s for i, s in enumerate(seen) if i == 0 or seen[i - 1] != s]

    def stop(self) -> None:
        self._client.close()
        self._thread.join(5)


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A two-sided saddle of 384 faces."""
    path = tmp_path_factory.mktemp("small") / "saddle.obj"
    V, F = saddle(80.0, 1 / 50, 1 / 50, rings=8)
    write_obj(path, V, F)
    return path


@pytest.fixture
def cached(tmp_path: Path) -> Iterator[tuple[Daemon, Path]]:
    """A daemon without a printer (a compile needs none), its compile cache in ``tmp_path/cache``."""
    cache = tmp_path / "cache"
    daemon = Daemon(tmp_path / "state", str(tmp_path / "no-printer"),
                    extra=f'[design]\npredict = false\ncache_dir = "{cache}"\n')
    try:
        daemon.start()
        yield daemon, cache
    finally:
        daemon.stop()


def compiled(api: httpx.Client, mesh: Path, parameters: dict[str, Any] = SMALL) -> tuple[str, Path, str]:
    """A job compiled from ``mesh``: its id, its folder and its ``compile.log``."""
    job = submit(api, mesh, start=False, parameters=parameters)
    ready = wait_for(api, job, "ready", timeout=180)
    folder = Path(ready["design_dir"]).parent
    return job, folder, (folder / "compile.log").read_text(encoding="utf-8", errors="replace")


def folder_bytes(folder: Path) -> dict[str, bytes]:
    """Every file of the job's ``design/`` and ``plans/``, by its path inside the job's folder."""
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for name in ("design", "plans") for p in sorted((folder / name).rglob("*")) if p.is_file()}


def programs(api: httpx.Client, job: str) -> dict[str, bytes]:
    return {name: api.get(f"/jobs/{job}/files/{name}").content
            for name in ("front.gcode", "back.gcode", "combined.gcode")}


def test_a_resubmitted_mesh_is_served_and_a_changed_input_is_compiled(
        cached: tuple[Daemon, Path], small: Path, tmp_path: Path) -> None:
    daemon, cache = cached
    api = daemon.client
    assert api is not None
    events = EventLog(daemon.url)
    try:
        first, first_dir, log = compiled(api, small)
        assert SERVED not in log
        entries = sorted(p.name for p in cache.iterdir())
        assert len(entries) == 1 and len(entries[0]) == 64            # one entry, by its SHA-256

        again, again_dir, log = compiled(api, small)
        assert SERVED in log and entries[0] in log
        assert folder_bytes(again_dir) == folder_bytes(first_dir)      # the same design, byte for byte
        assert programs(api, again) == programs(api, first)
        assert all(programs(api, again).values())
        assert api.get(f"/jobs/{again}").json()["verdict"] == api.get(f"/jobs/{first}").json()["verdict"]
        # the same events as a compile: every stage in its order, then the ready job's none
        assert events.stages(again) == events.stages(first)
        assert {"load", "flatten", "gcode", "write"} <= set(events.stages(again))
        states = [t["to_state"] for t in api.get(f"/jobs/{again}/transitions").json()]
        assert states == ["submitted", "compiling", "ready"]

        # a parameter changed: compiled, stored beside the first
        _, _, log = compiled(api, small, {**SMALL, "size": {"bbox_diagonal": 72}})
        assert SERVED not in log and len(list(cache.iterdir())) == 2
        # the same mesh with one byte more (a comment line): another file, compiled
        longer = tmp_path / small.name
        longer.write_bytes(small.read_bytes() + b"# one more line\n")
        _, _, log = compiled(api, longer)
        assert SERVED not in log and len(list(cache.iterdir())) == 3
    finally:
        events.stop()


def test_a_damaged_entry_is_compiled_again_never_served(cached: tuple[Daemon, Path], small: Path) -> None:
    """A cut program in the entry (as a disk full or a power cut leaves it): the next submit is
    compiled, its programs are the compile's (two compiles write the same bytes), and the entry
    is stored again, whole; then a new curvature table in the daemon is a miss too."""
    daemon, cache = cached
    api = daemon.client
    assert api is not None
    first, _, _ = compiled(api, small)
    (entry,) = cache.iterdir()
    cut = entry / "design" / "back.gcode"
    whole = cut.read_bytes()
    cut.write_bytes(whole[: len(whole) // 2])
    again, _, log = compiled(api, small)
    assert SERVED not in log
    assert programs(api, again) == programs(api, first)
    assert (entry / "design" / "back.gcode").read_bytes() == whole      # stored again, whole

    _, _, log = compiled(api, small)
    assert SERVED in log                                              # the restored entry serves
    shipped = (TABLE_DIR / "tpu95a-lycra-default.toml").read_text(encoding="utf-8")
    table = shipped.replace('name = "tpu95a-lycra-default"', 'name = "lycra-b"')
    assert table != shipped
    assert api.post("/tables", json={"toml": table}).status_code == 201
    _, _, log = compiled(api, small)
    assert SERVED not in log                                          # the daemon's tables changed
