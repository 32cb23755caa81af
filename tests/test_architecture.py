"""The house's rules (docs/architecture.md), checked on the source: the package root holds only what
every part shares, no function is longer than a screen, the imports go one way (engine <- daemon <-
api <- web; the client on the engine only; the simulator on nothing of ribbond; inside the engine,
mesh files <- design <- deploy, gcode <- pipeline <- panels), and the web page is no Python. The
checkers are plain functions over sources, so the last tests feed them bad modules and see them
fail."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "ribbond"

#: Modules the package root may hold at most (__init__, __main__, datafiles, ...).
MAX_ROOT_MODULES = 6
#: Lines a function may take (end_lineno - lineno + 1, decorators not counted, nested ones too).
MAX_FUNCTION_LINES = 80

#: The room of each top-level part of ribbond ("" is the package root itself).
ROOMS = {"": "engine", "datafiles": "engine", "mesh": "engine", "design": "engine", "deploy": "engine",
         "gcode": "engine", "printer": "engine", "calibration": "engine", "pipeline": "engine",
         "panels": "engine", "daemon": "daemon", "api": "api", "web": "web", "client": "client",
         "__main__": "entry"}
#: The rooms each room may import: the arrow engine <- daemon <- api <- web, the client beside it.
MAY_IMPORT = {"engine": {"engine"}, "daemon": {"engine", "daemon"}, "api": {"engine", "daemon", "api"},
              "web": {"engine", "daemon", "api", "web"}, "client": {"engine", "client"},
              "entry": {"engine", "daemon"}}
#: The one module that may import against the arrow: the daemon's entry point serves the API.
ENTRY_POINTS = {"ribbond.daemon.main": {"api"}}
#: Inside the engine, the parts each part may import besides itself and the root (datafiles): the mesh
#: files below the design engine; the design below the prediction (deploy) and the programs (gcode),
#: importing neither; the pipeline, which runs design, deploy and gcode in order, above the three;
#: the panels above the pipeline (a project is designs cut, compiled and sewn); calibration makes
#: its own design folders and programs (and lowers its priority as the pipeline's worker does).
ENGINE_MAY_IMPORT = {"": set(), "datafiles": set(), "mesh": set(), "printer": set(),
                     "design": {"mesh"},
                     "deploy": {"mesh", "design"},
                     "gcode": {"mesh", "design", "printer"},
                     "pipeline": {"mesh", "design", "deploy", "gcode"},
                     "panels": {"mesh", "design", "deploy", "gcode", "pipeline"},
                     "calibration": {"mesh", "design", "gcode", "printer", "pipeline"}}
#: The one engine module that may import against the engine's arrow: a design too large for one sheet
#: says how many panels ``--panels auto`` would cut it into, which only the cut can tell.
ENGINE_EXCEPTIONS = {"ribbond.pipeline.compile": {"panels"}}


def module_name(path: str) -> str:
    """``ribbond/daemon/main.py`` -> ``ribbond.daemon.main`` (a package is its ``__init__``)."""
    parts = list(Path(path).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def room(module: str) -> str:
    """The room of a module of ribbond (``sim`` for the simulator's, ``outside`` for any other)."""
    parts = module.split(".")
    if parts[0] != "ribbond":
        return "sim" if parts[0] == "sim" else "outside"
    return ROOMS.get(parts[1] if len(parts) > 1 else "", "unknown")


def part(module: str) -> str:
    """The top-level part of ribbond a module is in (``""`` for the package root's own modules)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def engine_allows(importer: str, target: str) -> bool:
    """Whether an engine module may import another engine module (``ENGINE_MAY_IMPORT``)."""
    have, want = part(importer), part(target)
    return (want in (have, "", "datafiles") or want in ENGINE_MAY_IMPORT.get(have, set())
            or want in ENGINE_EXCEPTIONS.get(importer, set()))


def imports(path: str, source: str, known: set[str]) -> Iterator[tuple[int, str, str]]:
    """Every import of a module, at any depth (inside functions too): ``(line, text, target)``,
    relative ones resolved; ``from X import name`` targets ``X.name`` when that is a module."""
    module = module_name(path)
    package = module if path.endswith("__init__.py") else module.rpartition(".")[0]
    tree = ast.parse(source, path)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            text = " ".join((ast.get_source_segment(source, node) or "").split())
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, text, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package.split(".")[:len(package.split(".")) - node.level + 1])
                base = ".".join(p for p in (base, node.module) if p)
            else:
                base = node.module or ""
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                yield node.lineno, text, sub if sub in known else base


def import_violations(sources: dict[str, str]) -> list[str]:
    """Imports against the arrow in ``sources`` (path -> text), each as ``path:line: import``."""
    known = {module_name(p) for p in sources}
    found = []
    for path, source in sources.items():
        importer = module_name(path)
        have = room(importer)
        for line, text, target in imports(path, source, known):
            want = room(target)
            if have == "sim":
                if want not in ("sim", "outside"):
                    found.append(f"{path}:{line}: {text} (the simulator imports nothing of ribbond)")
            elif want != "outside" and want not in MAY_IMPORT[have] | ENTRY_POINTS.get(importer, set()):
                found.append(f"{path}:{line}: {text} ({have} may not import {want})")
            elif have == want == "engine" and not engine_allows(importer, target):
                found.append(f"{path}:{line}: {text} ({part(importer)} may not import {part(target)})")
    return found


def long_functions(sources: dict[str, str], limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """Functions (nested ones too) longer than ``limit`` lines, each as ``path:line name (n lines)``."""
    found = []
    for path, source in sources.items():
        for node in ast.walk(ast.parse(source, path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1 if node.end_lineno else 0
                if length > limit:
                    found.append(f"{path}:{node.lineno} {node.name} ({length} lines)")
    return found


def _sources(*tops: str) -> dict[str, str]:
    return {str(p.relative_to(ROOT)): p.read_text(encoding="utf-8")
            for top in tops for p in sorted((ROOT / top).rglob("*.py"))}


# ----------------------------------------------------------------------------------- the house


def test_the_package_root_holds_only_what_every_part_shares() -> None:
    modules = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(modules) <= MAX_ROOT_MODULES, f"ribbond/ holds {len(modules)} modules: {modules}"


def test_no_function_is_longer_than_a_screen() -> None:
    found = long_functions(_sources("ribbond"))
    assert not found, "split into named steps:\n" + "\n".join(found)


def test_imports_go_one_way() -> None:
    found = import_violations(_sources("ribbond", "sim"))
    assert not found, "imports against the arrow (docs/architecture.md):\n" + "\n".join(found)


def test_the_design_engine_imports_neither_deploy_nor_gcode() -> None:
    sources = _sources("ribbond")
    known = {module_name(p) for p in sources}
    found = [f"{path}:{line}: {text}" for path, source in sources.items() if path.startswith("ribbond/design/")
             for line, text, target in imports(path, source, known)
             if part(target) in ("deploy", "gcode", "pipeline", "panels") and target.startswith("ribbond.")]
    assert not found, "the design engine is below deploy/, gcode/, pipeline/ and panels/:\n" + "\n".join(found)


def test_the_web_page_holds_no_python() -> None:
    assert sorted((PACKAGE / "web").rglob("*.py")) == []


def test_every_part_has_a_room() -> None:
    parts = {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()
             if (p.suffix == ".py" or p.is_dir()) and p.name != "__pycache__"}
    assert parts - {"__init__"} <= set(ROOMS), f"parts of ribbond/ with no room: {parts - set(ROOMS)}"


# -------------------------------------------------------------------------- the checks can fail


BAD = {
    "ribbond/__init__.py": "",
    "ribbond/design/__init__.py": "",
    "ribbond/pipeline/compile.py": "def f():\n    from ..daemon import jobs\n",
    "ribbond/daemon/__init__.py": "",
    "ribbond/daemon/jobs.py": "import json\nfrom ribbond.pipeline.compile import f\n",
    "ribbond/daemon/store.py": "from ribbond.api.app import create_app\n",
    "ribbond/daemon/main.py": "from ribbond.api.app import create_app\n",
    "ribbond/api/__init__.py": "",
    "ribbond/api/app.py": "from ..daemon.jobs import x\nfrom . import errors\n",
    "ribbond/api/errors.py": "",
    "ribbond/client/http.py": "import ribbond.daemon.config\nfrom ribbond.gcode import profiles\n",
    "ribbond/__main__.py": "from ribbond.daemon.main import main\nfrom ribbond import api\n",
    "sim/printer.py": "import serial\nfrom ribbond.printer import codec\n",
}

#: Imports against the engine's own arrow (and the pipeline's one allowed import of the cut).
BAD_ENGINE = {
    "ribbond/design/__init__.py": "",
    "ribbond/design/placement.py": "import numpy\nfrom ..gcode.profiles import FrameSpec\n",
    "ribbond/design/flatten.py": "from . import linalg\nfrom ribbond.mesh.files import write_obj\n"
                                 "def f():\n    from ribbond.deploy import predict\n",
    "ribbond/mesh/files.py": "from .errors import MeshError\nfrom ribbond.design.errors import DesignError\n",
    "ribbond/mesh/errors.py": "",
    "ribbond/deploy/predict.py": "from ribbond.design.format import Ribbon\nfrom ..pipeline.compile import design_mesh\n",
    "ribbond/gcode/program.py": "from ..datafiles import load_toml_model\nfrom ..deploy.predict import Prediction\n",
    "ribbond/pipeline/compile.py": "from ..deploy.predict import Prediction\ndef f():\n    from ..panels.project import cut_target\n",
    "ribbond/pipeline/repredict.py": "from ..panels.project import cut_target\n",
    "ribbond/panels/project.py": "from ..pipeline.compile import design_mesh\nfrom ..daemon import jobs\n",
}


def test_an_import_against_the_arrow_is_named_with_its_file_and_line() -> None:
    assert import_violations(BAD) == [
        "ribbond/pipeline/compile.py:2: from ..daemon import jobs (engine may not import daemon)",
        "ribbond/daemon/store.py:1: from ribbond.api.app import create_app (daemon may not import api)",
        "ribbond/client/http.py:1: import ribbond.daemon.config (client may not import daemon)",
        "ribbond/__main__.py:2: from ribbond import api (entry may not import api)",
        "sim/printer.py:2: from ribbond.printer import codec (the simulator imports nothing of ribbond)",
    ]


def test_a_long_function_is_named_nested_or_not() -> None:
    lines = [f"x{i} = {i}\n" for i in range(80)]
    short = "def short():\n" + "".join("    " + x for x in lines[:79])             # lines 1-80: 80 lines
    outer = "def outer():\n    async def inner():\n" + "".join("        " + x for x in lines)  # 82 and 81
    assert long_functions({"ribbond/m.py": short + "\n\n" + outer}) == ["ribbond/m.py:83 outer (82 lines)",
                                                                        "ribbond/m.py:84 inner (81 lines)"]


def test_an_import_against_the_engines_arrow_is_named_with_its_file_and_line() -> None:
    assert import_violations(BAD_ENGINE) == [
        "ribbond/design/placement.py:2: from ..gcode.profiles import FrameSpec (design may not import gcode)",
        "ribbond/design/flatten.py:4: from ribbond.deploy import predict (design may not import deploy)",
        "ribbond/mesh/files.py:2: from ribbond.design.errors import DesignError (mesh may not import design)",
        "ribbond/deploy/predict.py:2: from ..pipeline.compile import design_mesh (deploy may not import pipeline)",
        "ribbond/gcode/program.py:2: from ..deploy.predict import Prediction (gcode may not import deploy)",
        "ribbond/pipeline/repredict.py:1: from ..panels.project import cut_target (pipeline may not import panels)",
        "ribbond/panels/project.py:2: from ..daemon import jobs (engine may not import daemon)",
    ]
