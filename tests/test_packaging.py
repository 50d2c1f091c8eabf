"""The distribution installs one top-level import package, soiltrack (DESIGN.md section 1)."""
import importlib.metadata as md

import pytest


def test_only_soiltrack_is_top_level():
    try:
        dist = md.distribution("soiltrack")
    except md.PackageNotFoundError:
        pytest.skip("soiltrack is not installed in this environment (running from the source tree)")
    tops = (dist.read_text("top_level.txt") or "").split()
    assert tops in (["soiltrack"], [])
    for f in dist.files or []:
        parts = f.parts
        if parts[0].endswith((".dist-info", ".egg-info")) or parts[0] in ("..", "bin", "Scripts"):
            continue
        if parts[0].startswith("__editable__") or parts[0].endswith(".pth"):
            continue
        assert parts[0] == "soiltrack", f"installed file outside soiltrack/: {f}"


def test_subpackages_import_under_soiltrack():
    import soiltrack
    from soiltrack import identify, planning, soilmodel

    assert soilmodel.__name__ == "soiltrack.soilmodel"
    assert identify.__name__ == "soiltrack.identify" and planning.__name__ == "soiltrack.planning"
    assert soiltrack.TERRAINS is soilmodel.TERRAINS
    assert set(soilmodel.TERRAINS) == {"dry_sand", "sandy_loam", "clayey_soil", "heavy_clay", "lean_clay",
                                      "lete_sand", "snow"}
    assert set(soilmodel.VEHICLES) == {"heavy", "light"}
    assert soiltrack.fit is identify.fit and soiltrack.fit_many is identify.fit_many
