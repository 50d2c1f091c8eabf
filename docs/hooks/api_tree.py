"""MkDocs hook: lay out the import package as it installs, for the API reference.

setuptools maps the subpackages from sibling folders (``package-dir`` in pyproject.toml:
``soilmodel/`` installs as ``soiltrack.soilmodel``, and so on). The documentation tool reads
source files and would look for ``soiltrack/soilmodel/``. Before each build this hook copies
``soiltrack/`` and every mapped folder into ``build/api/soiltrack/`` (``build/`` is ignored by
git), the layout an installed ``soiltrack`` has, and mkdocs.yml points the reference there.
"""
from __future__ import annotations

import re
import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
API_TREE = ROOT / "build" / "api"
PACKAGE = "soiltrack"
_SECTION = re.compile(r"^\[tool\.setuptools\.package-dir\]\s*$(.*?)(?=^\[|\Z)", re.M | re.S)
_ENTRY = re.compile(r'^\s*"([\w.]+)"\s*=\s*"([^"]+)"\s*$', re.M)


def package_dirs(pyproject: Path) -> dict[str, Path]:
    """The ``package-dir`` table of pyproject.toml: import name -> source folder."""
    match = _SECTION.search(pyproject.read_text(encoding="utf-8"))
    if match is None:
        raise RuntimeError(f"{pyproject}: no [tool.setuptools.package-dir] table")
    return {name: ROOT / folder for name, folder in _ENTRY.findall(match.group(1))}


def build_tree() -> Path:
    """Copy the package into ``build/api/`` in its installed layout; return that folder."""
    mapping = package_dirs(ROOT / "pyproject.toml")
    shutil.rmtree(API_TREE, ignore_errors=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in sorted(mapping, key=lambda n: n.count(".")):  # parents before children
        if name != PACKAGE and not name.startswith(PACKAGE + "."):
            continue
        target = API_TREE.joinpath(*name.split("."))
        shutil.copytree(mapping[name], target, ignore=ignore, dirs_exist_ok=True)
    return API_TREE


def on_startup(command: str, dirty: bool) -> None:  # noqa: ARG001 - the MkDocs hook signature
    """MkDocs event, before the configuration: the handler drops search paths that do not exist."""
    build_tree()


def on_pre_build(config, **kwargs) -> None:  # noqa: ARG001 - the MkDocs hook signature
    """MkDocs event: refresh the copied tree before each build (``mkdocs serve`` rebuilds)."""
    build_tree()
