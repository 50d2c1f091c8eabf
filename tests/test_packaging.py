"""The distribution installs one top-level import package, soiltrack (docs/index.md)."""

import importlib.metadata as md
import pytest


def _installed_dists():
    """Installed (.dist-info) distributions of soiltrack; a source-tree egg-info is not an install."""
    return [d for d in md.distributions(name="soiltrack") if str(getattr(d, "_path", "")).endswith(".dist-info")]


def test_only_soiltrack_is_top_level():
    dists = _installed_dists()
    if not dists:
        pytest.skip("soiltrack is not installed in this environment (running from the source tree)")
    for dist in dists:
        tops = (dist.read_text("top_level.txt") or "").split()
        assert tops in (["soiltrack"], []), tops
        for f in dist.files or []:
            top = f.parts[0]
            if top.endswith(".dist-info") or top in ("..", "bin", "Scripts"):
                continue
            if "__editable__" in str(f):  # editable install: setuptools' finder module and .pth hook
                continue
            assert top == "soiltrack", f"installed file outside soiltrack/: {f}"


def test_subpackages_import_under_soiltrack():
    import soiltrack
    from soiltrack import identify, planning, soilmodel

    assert soilmodel.__name__ == "soiltrack.soilmodel"
    assert identify.__name__ == "soiltrack.identify" and planning.__name__ == "soiltrack.planning"
    assert soiltrack.TERRAINS is soilmodel.TERRAINS
    assert set(soilmodel.TERRAINS) == {
        "dry_sand",
        "sandy_loam",
        "clayey_soil",
        "heavy_clay",
        "lean_clay",
        "lete_sand",
        "snow",
    }
    assert set(soilmodel.VEHICLES) == {"heavy", "light"}
    assert soiltrack.fit is identify.fit and soiltrack.fit_many is identify.fit_many


def test_every_subpackage_folder_is_installed():
    """A folder with an ``__init__.py`` that pyproject.toml does not list is missing from ``pip install .``."""
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    cfg = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    top = {
        "soiltrack": "soiltrack",
        "soilmodel": "soiltrack.soilmodel",
        "identify": "soiltrack.identify",
        "planning": "soiltrack.planning",
    }
    found = set()
    for folder, pkg in top.items():
        for init in (root / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(root / folder).parts
            found.add(".".join((pkg, *rel)))
    assert found - listed == set()
