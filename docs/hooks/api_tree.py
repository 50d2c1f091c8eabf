"""MkDocs hook: lay out the import package as it installs, for the API reference.

setuptools maps the subpackages from sibling folders (``package-dir`` in pyproject.toml:
``soilmodel/`` installs as ``soiltrack.soilmodel``, and so on). The documentation tool reads
source files and would look for ``soiltrack/soilmodel/``. Before each build this hook copies
``soiltrack/`` and every mapped folder into ``build/api/soiltrack/`` (``build/`` is ignored by
git), the layout an installed ``soiltrack`` has, and mkdocs.yml points the reference there.
"""

from __future__ import annotations

import ast
import re
import shutil
from pathlib import Path

from mkdocs.exceptions import PluginError

ROOT = Path(__file__).resolve().parents[2]
API_TREE = ROOT / "build" / "api"
PACKAGE = "soiltrack"
_SECTION = re.compile(r"^\[tool\.setuptools\.package-dir\]\s*$(.*?)(?=^\[|\Z)", re.M | re.S)
_ENTRY = re.compile(r'^\s*"([\w.]+)"\s*=\s*"([^"]+)"\s*$', re.M)
#: Reference page (under docs/, without ".md") of each public package: every name of the package's
#: ``__all__`` must have an entry there, or the build fails (a name hidden by a module of the same
#: name, or a new export nobody documented, would otherwise vanish from the reference silently).
REFERENCE_PAGES = {
    "soiltrack": "reference/soiltrack",
    "soiltrack.soilmodel": "reference/soilmodel",
    "soiltrack.identify": "reference/identify",
    "soiltrack.planning": "reference/planning",
}
#: A Sphinx role before inline code in a rendered docstring (``:func:`fit``` renders as ":func:<code>").
_ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|exc|obj):(?=<code)")
_ANCHOR = re.compile(r'id="(soiltrack(?:\.\w+)+)"')


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


def exported_names(package: str) -> list[str]:
    """The public names of ``package`` from its ``__init__.py`` in the copied tree (static, no import)."""
    init = API_TREE.joinpath(*package.split("."), "__init__.py")
    for node in ast.parse(init.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return [str(v) for v in ast.literal_eval(node.value)]
    return []


def _is_entry(anchor: str, package: str) -> bool:
    """Whether ``anchor`` is a top entry of ``package``: ``package.name`` or ``package.module[...].name``."""
    if not anchor.startswith(package + "."):
        return False
    modules = anchor[len(package) + 1 :].split(".")[:-1]
    folder = API_TREE.joinpath(*package.split("."), *modules)
    return not modules or folder.with_suffix(".py").is_file() or (folder / "__init__.py").is_file()


def missing_entries(site_dir: Path) -> dict[str, list[str]]:
    """Per package, the exported names that have no entry on its reference page of the built site."""
    missing = {}
    for package, page in REFERENCE_PAGES.items():
        html = (site_dir / page / "index.html").read_text(encoding="utf-8")
        anchors = {a.rsplit(".", 1)[-1] for a in _ANCHOR.findall(html) if _is_entry(a, package)}
        subpackages = {n.split(".")[-1] for n in REFERENCE_PAGES}
        names = [
            n for n in exported_names(package) if not n.startswith("_") and n not in subpackages and n not in anchors
        ]
        if names:
            missing[package] = names
    return missing


def on_page_content(html: str, **kwargs) -> str:  # noqa: ARG001 - the MkDocs hook signature
    """MkDocs event: drop the Sphinx roles the docstrings use, which Markdown shows as text."""
    return _ROLE.sub("", html)


def on_post_build(config, **kwargs) -> None:  # noqa: ARG001 - the MkDocs hook signature
    """MkDocs event: fail the build when an exported name has no entry in the API reference."""
    missing = missing_entries(Path(config["site_dir"]))
    if missing:
        lines = "; ".join(f"{pkg}: {', '.join(names)}" for pkg, names in missing.items())
        raise PluginError(
            f"exported names without an entry in the API reference: {lines} "
            "(add a '::: module.name' entry on the package's page under docs/reference/)"
        )
