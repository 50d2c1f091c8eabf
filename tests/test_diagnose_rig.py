"""Sweeps shaped like a test rig's: zero-slip rows, few points, a soil outside the practical range."""

import pytest

import json
import math
import os

import numpy as np

from conftest import bench_module
from soiltrack.identify import diagnose
from soiltrack.soilmodel import SlipData, Vehicle

HERE = os.path.dirname(os.path.abspath(__file__))
HEAVY = Vehicle.from_json(os.path.join(os.path.dirname(HERE), "examples", "data", "heavy_vehicle.json"))
SLIPS = np.array([0.0, 0.0, 0.02, 0.04, 0.06, 0.08, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7])


def _fmax(c=1.3e3, phi_deg=31.1, W=329e3, A=2.8):
    return A * c + W * math.tan(math.radians(phi_deg))


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_a_humped_rig_sweep_with_zero_slip_rows_is_diagnosed():
    # a strain-softening sweep with two rows at zero slip: the plateau check fits the soil on the readings
    # below each trial level, and one of those subsets has a single nonzero slip; that fit is impossible
    # and must count as a failed trial, not stop the diagnosis as bad input (it used to exit 2)
    rng = np.random.default_rng(5)
    jr = SLIPS * 2.8
    shape = (1 - np.exp(-jr / 0.02)) * (1 + 0.6 * np.exp(-jr / 0.3))
    dp = 0.8 * _fmax() * shape - 0.05 * 329e3 + 800.0 * rng.standard_normal(SLIPS.size)
    d = diagnose(SlipData(slip=SLIPS, drawbar_pull=dp, source="rig.csv"), HEAVY)
    assert d.converged and d.verdict == "hump_shear", (d.verdict, d.notes)
    # the gap is 35 x the noise floor, and the report's own tests say there is one
    ch = "drawbar_pull_N"
    assert d.holdout_rmse_before[ch] > 10 * d.noise[ch]
    assert d.gap.present


LIGHT = Vehicle.from_json(os.path.join(os.path.dirname(HERE), "examples", "data", "light_vehicle.json"))
_light_sweep = bench_module("soil_range_and_torque_hold").light_sweep  # effect-free, independent numpy


@pytest.mark.slow
def test_a_soil_beyond_the_practical_range_is_not_read_as_an_effect():
    # K = 3 mm (a firm soil under a small rig track) lies below the practical range's 6 mm: the nominal fit
    # ends on that bound, misses the steep rise, and an effect that bends the curve (hump_shear) was named
    # with confidence 1. The data want the soil beyond the bound: the diagnosis widens and finds no gap
    data = _light_sweep(K=0.003)
    d = diagnose(data, LIGHT)
    assert (d.verdict, d.cause) == ("unexplained", "soil_beyond_range"), (d.verdict, d.cause, d.reason)
    assert d.cause_detail["outside_practical_range"] == ["shear_modulus_m"]
    assert d.soil_before["at_bound"] == {"shear_modulus_m": "lower"}
    assert json.loads(d.to_json())["cause"] == "soil_beyond_range"


def test_a_soil_inside_the_practical_range_is_diagnosed_within_it():
    d = diagnose(_light_sweep(K=0.012), LIGHT)
    assert d.verdict == "none" and not d.gap.present, (d.verdict, [t.to_dict() for t in d.gap.tests])
    assert d.soil_before["at_bound"].get("shear_modulus_m") is None
    assert d.soil_before["outside_practical_range"] == []
    assert "soil_beyond_range" in [x.name for x in d.excluded]  # not formed: the soil is on no edge


@pytest.mark.slow
def test_the_command_line_keeps_or_widens_the_bounds(tmp_path, capsys):
    from soiltrack.cli import main
    from soiltrack.soilmodel import write_csv

    path = str(tmp_path / "small_rig.csv")
    write_csv(_light_sweep(K=0.003), path)
    out = {}
    for b in ("practical", "auto", "wide"):
        assert main(["diagnose", path, "--vehicle", "light", "--json", "--quiet", "--bounds", b]) == 0
        out[b] = json.loads(capsys.readouterr().out)
    assert out["practical"]["soil_before"]["at_bound"] == {"shear_modulus_m": "lower"}
    assert out["practical"]["verdict"] != "none"  # given bounds: the wider soil is no hypothesis
    assert (out["auto"]["verdict"], out["auto"]["cause"]) == ("unexplained", "soil_beyond_range")
    assert out["wide"]["verdict"] == "none"
    assert out["wide"]["soil_before"]["outside_practical_range"] == ["shear_modulus_m"]
    import subprocess
    import sys

    bad = subprocess.run(
        [sys.executable, "-m", "soiltrack", "diagnose", path, "--vehicle", "light", "--bounds", "loose"],
        capture_output=True,
        text=True,
    )
    assert bad.returncode == 2 and "--bounds" in bad.stderr and "Traceback" not in bad.stderr


@pytest.mark.slow
@pytest.mark.parametrize("exponent", [1.0, 0.0])
def test_the_measured_sinkage_shows_the_slip_sinkage_signature(exponent):
    """A track sweep with sinkage_m: the diagnosis carries the sinkage's growth with the slip (Lyasko's law
    simulated: found, exponent near 1; static sinkage: not found)."""
    from soiltrack.soilmodel import TERRAINS, VEHICLES
    from soiltrack.soilmodel.simulation import simulate_slip_sweep

    v = VEHICLES["light"]
    data = simulate_slip_sweep(
        v, TERRAINS["sandy_loam"], normal_loads=(300.0, 450.0), seed=3, sinkage_slip_exponent=exponent
    )
    d = diagnose(data, v)
    ev = json.loads(d.to_json())["sinkage_evidence"]
    assert ev["testable"] and ev["n_rows"] == data.n_samples
    assert abs(ev["exponent"] - exponent) < 3 * ev["stderr"] + 0.05
    assert d.sinkage.found() is (exponent > 0)
