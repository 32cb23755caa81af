"""The README is an entrance and the pages it links stay true: short, every link resolves, every path
and module named exists.

Checked in README.md, DEVELOPERS.md and docs/*.md. Markdown is read with a few regular expressions
(links, headings, paths in the text); the pages are ours, so the checks need not handle Markdown at
large, only fail where a page names something that is not there.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = sorted([README, ROOT / "DEVELOPERS.md", *(ROOT / "docs").glob("*.md")])
README_MAX_LINES = 300

# [text](target) and ![alt](target); the target ends at whitespace or ")"
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
# a path in the project: ribbond/..., tests/..., bench/..., sim/..., systemd/... not preceded by a
# path character (so /etc/ribbond/... and ribbond-design/3 are not taken); a glob (*.toml) is allowed.
# examples/ is left out: the pages name the meshes make_meshes.py generates there.
PROJECT_PATH = re.compile(r"(?<![\w/.-])(?:ribbond|tests|bench|sim|systemd)/[\w./*-]*")
PYTHON_M = re.compile(r"python -m ([\w.]+)")
FENCE = re.compile(r"^(```|~~~)")


def _rel(page: Path) -> str:
    return str(page.relative_to(ROOT))


def _outside_code(text: str) -> str:
    """The page without its fenced code blocks (links there are not links)."""
    keep, fenced = [], False
    for line in text.splitlines():
        if FENCE.match(line.strip()):
            fenced = not fenced
            continue
        if not fenced:
            keep.append(line)
    return "\n".join(keep)


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    headings = re.findall(r"^#{1,6}\s+(.*?)\s*#*$", _outside_code(page.read_text()), re.MULTILINE)
    return {_slug(h) for h in headings}


def links(page: Path) -> list[str]:
    """The relative link targets of a page (web addresses and mail left out)."""
    found = LINK.findall(_outside_code(page.read_text()))
    return [t for t in found if not re.match(r"^[a-z][a-z0-9+.-]*:", t)]


def broken_links(page: Path) -> list[str]:
    """Each link whose file does not exist, or whose anchor names no heading of that file."""
    broken = []
    for target in links(page):
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            broken.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            broken.append(f"{target}: no heading #{anchor} in {dest.relative_to(ROOT)}")
    return broken


def missing_paths(page: Path) -> list[str]:
    """Each project path the page names that does not exist (a glob: that matches nothing)."""
    missing = []
    for raw in sorted(set(PROJECT_PATH.findall(page.read_text()))):
        path = raw.rstrip(".,:;")
        if "*" in path:
            if not list(ROOT.glob(path)):
                missing.append(path)
        elif not (ROOT / path).exists():
            missing.append(path)
    return missing


def missing_modules(page: Path) -> list[str]:
    """Each module of a `python -m X` the page names that cannot be found."""
    missing = []
    for name in sorted(set(PYTHON_M.findall(page.read_text()))):
        name = name.rstrip(".")
        try:
            found = importlib.util.find_spec(name) is not None
        except ModuleNotFoundError:
            found = False
        if not found:
            missing.append(name)
    return missing


def test_readme_is_short():
    lines = len(README.read_text().splitlines())
    assert lines <= README_MAX_LINES, f"README.md has {lines} lines; at most {README_MAX_LINES}: move text to docs/"


def test_every_docs_page_is_linked_from_the_readme():
    linked = {(README.parent / t.partition("#")[0]).resolve() for t in links(README)}
    unlinked = [_rel(p) for p in (ROOT / "docs").glob("*.md") if p.resolve() not in linked]
    assert not unlinked, f"docs pages the README does not link: {unlinked}"


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_links_resolve(page):
    assert not broken_links(page), f"{_rel(page)}: {broken_links(page)}"


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_named_project_paths_exist(page):
    assert not missing_paths(page), f"{_rel(page)} names paths that do not exist: {missing_paths(page)}"


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_named_modules_exist(page):
    assert not missing_modules(page), f"{_rel(page)} names `python -m` modules that do not exist: {missing_modules(page)}"


def test_the_checks_can_fail(tmp_path, monkeypatch):
    """Each check finds what is wrong in a page made to be wrong."""
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    (tmp_path / "ribbond").mkdir()
    (tmp_path / "ribbond" / "real.py").write_text("")
    (tmp_path / "tests").mkdir()
    (tmp_path / "there.md").write_text("# A heading `here`\n")
    page = tmp_path / "page.md"
    page.write_text(
        "[ok](there.md) [ok](there.md#a-heading-here) [gone](nowhere.md) [bad](there.md#nothing)\n"
        "[web](https://example.org/x) `ribbond/real.py` `ribbond/gone.py` `ribbond/*.py` `ribbond/*.toml`\n"
        "tests/gone.py: examples/meshes/made.obj\n"
        "/etc/ribbond/ribbond.toml ribbond-design/3\n"
        "python -m json.tool, python -m ribbond_no_such_module\n"
        "```\n[in code](not-a-link.md)\n```\n"
    )
    assert broken_links(page) == ["nowhere.md: no such file", "there.md#nothing: no heading #nothing in there.md"]
    assert missing_paths(page) == ["ribbond/*.toml", "ribbond/gone.py", "tests/gone.py"]
    assert missing_modules(page) == ["ribbond_no_such_module"]
