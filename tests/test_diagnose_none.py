"""The verdict ``none`` says how sure it is (issue 37 item 4): measured on effect-free sweeps as a new user
makes them (``soiltrack simulate --kind sweep``)."""

from __future__ import annotations

import pytest

from soiltrack.cli import main
from soiltrack.identify import diagnose
from soiltrack.soilmodel import VEHICLES, read_csv


@pytest.mark.slow
@pytest.mark.parametrize(
    "vehicle, terrain, seed, nominal, confidence",
    [
        ("heavy", "lete_sand", 1, 0.032, 1.0),
        ("heavy", "lete_sand", 2, 0.183, 0.964),
        ("light", "dry_sand", 1, 0.329, 0.538),
    ],
)
def test_none_on_an_effect_free_sweep_carries_the_no_gap_weight(
    tmp_path, capsys, vehicle, terrain, seed, nominal, confidence
):
    path = tmp_path / "sweep.csv"
    assert (
        main(
            [
                "simulate",
                "--kind",
                "sweep",
                "--vehicle",
                vehicle,
                "--terrain",
                terrain,
                "--seed",
                str(seed),
                "-o",
                str(path),
            ]
        )
        == 0
    )
    capsys.readouterr()
    d = diagnose(read_csv(str(path)), VEHICLES[vehicle])
    w = {r.effect: r.weight for r in d.ranking}
    # before: confidence = the nominal model's own weight (0.03 on the first: "none (0.03)")
    assert d.verdict == "none" and w["none"] == pytest.approx(nominal, abs=0.001)
    assert d.confidence == pytest.approx(confidence, abs=0.001) and d.confidence >= w["none"]
    assert "no-gap hypothesis" in d.reason
