"""The daemon's curvature-table library (issue 15): the shipped tables and the daemon's own
(``<state_dir>/tables/NAME.toml``, added from a measured calibration), by name.

A design names its table; the daemon never reads a file a client points at, so a path is refused.
"""

from __future__ import annotations

import logging
import os
import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ribbond.design.thickness import TABLE_NAME, CurvatureTable, available_tables, load_curvature_table
from ..jobs import JobState
from ..records import NotFound, ServiceError
from ..store import JobStore

log = logging.getLogger(__name__)


class TableLibrary:
    """The curvature tables a design may name; the store says which compiles use one."""

    def __init__(self, state_dir: Path, store: JobStore) -> None:
        self.tables_dir = Path(state_dir) / "tables"
        self.store = store

    def table_names(self) -> dict[str, str]:
        """Every table a design may name: ``name -> "shipped" | "daemon"``."""
        names = {n: "shipped" for n in available_tables()}
        if self.tables_dir.is_dir():
            names.update({p.stem: "daemon" for p in self.tables_dir.glob("*.toml") if TABLE_NAME.match(p.stem)})
        return dict(sorted(names.items()))

    def check_table_name(self, name: Any) -> None:
        """A design's ``curvature_table`` must name a known table: a path is refused (the daemon reads no
        file a client points at)."""
        known = self.table_names()
        if not isinstance(name, str) or name not in known:
            what = "is a path, not a table name" if isinstance(name, str) and ("/" in name or "\\" in name
                                                                              or name.endswith(".toml")) else "is unknown"
            raise ValueError(f"curvature_table {name!r} {what}; the daemon's tables: {', '.join(known)} "
                             "(add one with 'ribbonctl tables add FILE')")

    def check_prestretch(self, name: str, prestretch: float) -> None:
        """A design's ``prestretch`` must be the one its table was measured at (the compile refuses
        it otherwise, after the upload): ValueError naming both."""
        table, _ = self._table(name)
        if abs(table.prestretch - prestretch) > 1e-9:
            raise ValueError(f"prestretch = {prestretch:g}: the curvature table {name!r} was measured at "
                             f"pre-stretch s = {table.prestretch:g}; give prestretch = {table.prestretch:g}, or "
                             "a curvature_table measured at that pre-stretch (GET /tables, 'ribbonctl tables')")

    def _table(self, name: str) -> tuple[CurvatureTable, str]:
        source = self.table_names().get(name)
        if source is None:
            raise NotFound(f"no curvature table {name!r}; tables: {', '.join(self.table_names())}")
        return load_curvature_table(name, tables_dir=self.tables_dir), source

    def tables(self) -> list[dict[str, Any]]:
        """Each table's name, source and what it was measured on (or why it cannot be read)."""
        out = []
        for name, source in self.table_names().items():
            try:
                t, _ = self._table(name)
                out.append({"name": name, "source": source, "material": t.material, "fabric": t.fabric,
                            "prestretch": t.prestretch, "description": t.description})
            except ValueError as exc:
                out.append({"name": name, "source": source, "error": str(exc)})
        return out

    def table(self, name: str) -> dict[str, Any]:
        """One table in full, with its source."""
        t, source = self._table(name)
        return {"source": source, **t.model_dump(mode="json")}

    def add_table(self, text: str) -> dict[str, Any]:
        """Add (or replace) a daemon table from the text of its TOML file; its ``name`` names it.

        Raises ValueError for an invalid table (the field named), a name that is not a plain name, or
        the name of a shipped table."""
        table = _parse_table(text)
        self.tables_dir.mkdir(parents=True, exist_ok=True)
        path = self.tables_dir / f"{table.name}.toml"
        tmp = path.with_suffix(".tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)                                  # a compile never reads half a table
        log.info("curvature table %s added", table.name)
        return {"source": "daemon", **table.model_dump(mode="json")}

    def remove_table(self, name: str) -> None:
        """Remove a daemon table; refused for a shipped one and while a compile uses it."""
        source = self.table_names().get(name)
        if source is None:
            raise NotFound(f"no curvature table {name!r}")
        if source == "shipped":
            raise ServiceError(f"{name!r} is a shipped table: it cannot be removed")
        users = [j.id for j in self.store.active() if j.state in (JobState.SUBMITTED, JobState.COMPILING)
                 and j.parameters.get("curvature_table") == name]
        if users:
            raise ServiceError(f"table {name!r} is used by job(s) {', '.join(users)} being compiled")
        (self.tables_dir / f"{name}.toml").unlink()


def _parse_table(text: str) -> CurvatureTable:
    """The table in ``text`` (TOML), checked: ValueError naming the field, the name or the TOML error."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"the curvature table is not valid TOML: {exc}") from None
    try:
        table = CurvatureTable(**data)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or '(file)'}: {e['msg']}" for e in exc.errors())
        raise ValueError(f"invalid curvature table: {problems}") from None
    if not TABLE_NAME.match(table.name):
        raise ValueError(f"table name {table.name!r}: letters, digits, '-' and '_' only (at most 64)")
    if table.name in available_tables():
        raise ValueError(f"{table.name!r} is a shipped table: give yours another name")
    return table
