"""A track sweep and a drive log in one joint fit (identify.datasets, kinds ``track`` and ``drivelog``).

The sweeps are simulated here with numpy (Eq. 2 written out, not the library's thrust); the logs by the
library's drive simulator (its dynamics and sensor noise, fitted by the drive-log fit the joint fit calls).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, ShearTest, SlipData, Soil
from soiltrack.soilmodel.simulation import simulate_drive_log

V = VEHICLES["light"]
SOIL = TERRAINS["dry_sand"]
C, PHI, K = SOIL.cohesion, SOIL.friction_angle, SOIL.shear_modulus


def _sweep(seed: int, loads, phi: float = PHI, sd: float = 3.0) -> SlipData:
    """Tractive force against slip at ``loads`` (12 slips each): Eq. 2 in numpy, Gaussian noise ``sd`` N."""
    rng = np.random.default_rng(seed)
    i = np.tile(np.linspace(0.03, 0.6, 12), len(loads))
    W = np.repeat(np.asarray(loads, dtype=float), 12)
    A, l = 2 * V.track_width * V.track_length, V.track_length
    F = (A * C + W * math.tan(phi)) * (1 - K / (i * l) * (1 - np.exp(-i * l / K)))
    return SlipData(slip=i, tractive_force=F + rng.normal(0, sd, i.size), normal_load=W, source=f"sweep {seed}")


def _shear(seed: int) -> ShearTest:
    rng = np.random.default_rng(seed)
    sig = np.repeat([5e3, 10e3, 15e3], 10)
    j = np.tile(np.linspace(0.002, 0.1, 10), 3)
    tau = (C + sig * math.tan(PHI)) * -np.expm1(-j / K) + rng.normal(0, 60, sig.size)
    return ShearTest(normal_pressure=sig, shear_displacement=j, shear_stress=tau, source="shear")


@pytest.fixture(scope="module")
def log():
    return simulate_drive_log(V, SOIL, seed=1)


@pytest.mark.slow
def test_a_sweep_and_a_log_of_one_soil_agree_and_hold_the_truth(log):
    W = V.weight
    r = fit([_sweep(1, [0.5 * W, 1.5 * W]), log], V, labels=["sweep", "log"])
    assert r.outcome == "usable", r.fit_outcome.reason
    c = r.consistency
    # sweep at two loads: rank 3 (c, phi, K); log: rank 2 (F_max, K); joint 3
    assert c["dof"] == 2 and c["p_value"] > 0.01 and not c["poor_fit"]
    for key, v in (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K)):
        e = r.parameters[key]
        assert e.identifiable and e.edge_ci95[0] <= v <= e.edge_ci95[1], (key, e.edge_ci95, v)
    kinds = [d["kind"] for d in r.datasets]
    assert kinds == ["track_sweep", "drive_log"]
    assert r.datasets[1]["gear"]["kind"] == "track" and r.datasets[1]["outcome"] == "usable"
    # the log alone does not separate c from phi; K it determines (its shift is a number)
    assert r.datasets[1]["soil"]["cohesion_kpa"] is None
    assert c["shifts_se"]["shear_modulus_m"][1] is not None and abs(c["shifts_se"]["shear_modulus_m"][1]) < 3
    assert not any("on a bound" in n for n in r.notes)  # the Bekker parameters are not in these data
    json.loads(r.to_json())


@pytest.mark.slow
def test_a_log_on_another_soil_is_named_as_disagreeing(log):
    W = V.weight
    other = Soil(cohesion=C, friction_angle=math.radians(34.0), shear_modulus=K, name="firmer")
    bad = simulate_drive_log(V, other, seed=2)
    r = fit([_sweep(1, [0.5 * W, 1.5 * W]), _shear(4), bad], V, labels=["sweep", "shear", "log other soil"])
    c = r.consistency
    assert r.outcome == "poor_fit" and c["poor_fit"] and c["p_value"] < 1e-4
    assert c["disagrees"] == "log other soil", c["contributions"]
    assert "log other soil" in r.fit_outcome.reason


@pytest.mark.slow
def test_a_one_load_sweep_with_a_shear_test_separates_c_and_phi():
    """At one load a track sweep sees only F_max and K; a shear test beside it separates c from phi."""
    r = fit([_sweep(3, [V.weight]), _shear(5)], [V, None], labels=["sweep", "shear"])
    assert r.outcome == "usable" and r.consistency["p_value"] > 0.01
    assert r.datasets[0]["soil"]["cohesion_kpa"] is None  # alone: c and phi confounded
    for key, v in (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K)):
        e = r.parameters[key]
        assert e.identifiable and e.edge_ci95[0] <= v <= e.edge_ci95[1], (key, e.edge_ci95, v)


def test_a_wheel_sweep_with_a_vehicle_or_a_log_with_a_wheel_is_refused():
    from soiltrack.soilmodel.rigid_wheel import RigidWheel
    from soiltrack.soilmodel.wheel_sweep import WheelSweep

    w = WheelSweep(slip=np.array([0.1, 0.2, 0.3]), drawbar_pull=np.ones(3), normal_load=np.full(3, 50.0))
    with pytest.raises(DataError, match="needs a RigidWheel"):
        fit([w, _shear(1)], V)
    t = np.arange(20) * 0.1
    from soiltrack.soilmodel import DriveLog

    dl = DriveLog(time=t, sprocket_torque=np.ones(20), sprocket_speed=np.ones(20), vehicle_speed=np.full(20, 0.05))
    with pytest.raises(DataError, match="needs a tracked Vehicle"):
        fit([dl, _shear(1)], [RigidWheel(0.1, 0.05), None])


@pytest.mark.slow
def test_cli_joint_fit_of_a_track_sweep_and_a_log(tmp_path, capsys, log):
    from soiltrack.soilmodel import write_csv

    W = V.weight
    a, b = tmp_path / "sweep.csv", tmp_path / "log.csv"
    write_csv(_sweep(1, [0.5 * W, 1.5 * W]), a)
    write_csv(log, b)
    assert main(["fit", str(a), str(b), "--vehicle", "light", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [d["kind"] for d in out["datasets"]] == ["track_sweep", "drive_log"]
    assert out["consistency"]["p_value"] > 0.01
