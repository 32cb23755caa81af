"""Data files the user can replace: shipped TOML files by name, or the user's own by path.

Printer profiles (``ribbond/gcode/profiles/``) and curvature tables (``ribbond/design/tables/``)
are both pydantic models read from TOML; this module finds and validates them the same way.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import TypeVar

from pydantic import BaseModel, ValidationError

M = TypeVar("M", bound=BaseModel)


def shipped_names(directory: Path) -> list[str]:
    """Names (file stems) of the ``.toml`` files shipped in ``directory``."""
    return sorted(p.stem for p in directory.glob("*.toml"))


def toml_path(name_or_path: str | Path, directory: Path) -> Path:
    """The file a name or path means: a path ending in ``.toml`` as it is, a name as
    ``<directory>/<name>.toml`` (whether it exists is the caller's question)."""
    path = Path(name_or_path)
    return path if path.suffix == ".toml" else directory / f"{name_or_path}.toml"


def load_toml_model(name_or_path: str | Path, directory: Path, model: type[M], kind: str) -> M:
    """The file ``<directory>/<name>.toml`` for a name, or the ``.toml`` file at a path, as ``model``.

    Raises
    ------
    ValueError
        naming the file and what is wrong with it (each invalid field by its path), or, for an
        unknown name, listing the shipped ones. ``kind`` names the file in messages
        ("printer profile", "curvature table").
    """
    path = toml_path(name_or_path, directory)
    if Path(name_or_path).suffix != ".toml":
        if not path.is_file():
            raise ValueError(f"unknown {kind} {str(name_or_path)!r}; shipped: "
                             f"{', '.join(shipped_names(directory))}, or give the path of a .toml file")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the {kind}: {exc}") from None
    try:
        return model(**data)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or '(file)'}: {e['msg']}"
                             for e in exc.errors())
        raise ValueError(f"{path}: invalid {kind}: {problems}") from None
