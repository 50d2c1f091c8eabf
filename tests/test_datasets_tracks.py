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


def _rig_sweep(seed: int, with_std: bool = True) -> SlipData:
    """A rig sweep at two loads, 8 slips repeated 3 times, noise growing with the force (sd 1 N + 3 % of F) and
    logged per row in ``tractive_force_std_N`` (Eq. 2 in numpy)."""
    rng = np.random.default_rng(seed)
    i = np.tile(np.repeat(np.linspace(0.03, 0.6, 8), 3), 2)
    W = np.repeat([0.5 * V.weight, 1.5 * V.weight], 24)
    A, l = 2 * V.track_width * V.track_length, V.track_length
    F = (A * C + W * math.tan(PHI)) * (1 - K / (i * l) * (1 - np.exp(-i * l / K)))
    sd = 1.0 + 0.03 * F
    y = F + rng.normal(0, sd)
    return SlipData(slip=i, tractive_force=y, normal_load=W, force_std=sd if with_std else None, source=f"rig {seed}")


def _plate(seed: int):
    """A plate test (Bekker, numpy): its parameters are not the sweep's, so the joint sweep block is its own."""
    from soiltrack.soilmodel import PlateTest

    rng = np.random.default_rng(seed)
    b = np.repeat([0.05, 0.1], 8)
    z = np.tile(np.linspace(0.005, 0.04, 8), 2)
    pr = (1e3 / b + 1.5e6) * z**1.1
    return PlateTest(plate_width=b, sinkage=z, pressure=pr * (1 + rng.normal(0, 0.02, z.size)), source="plate")


KEYS = ("cohesion_kpa", "friction_angle_deg", "shear_modulus_m")


@pytest.mark.parametrize("measured", ["tractive_force", "drawbar_pull"])
def test_a_weighted_sweep_enters_the_joint_fit_as_its_single_fit(measured):
    """Per-row std column (and repeats): the sweep's block alone is the single fit's weighted least squares - the
    same estimate and standard errors; beside a plate test (disjoint parameters) the joint c, phi, K are the
    single fit's and their covariance the single fit's up to the one pooled noise factor. A drawbar-pull sweep
    (the thrust less mu_r W, its std column ``drawbar_pull_std_N``) the same way."""
    d = _rig_sweep(11)
    if measured == "drawbar_pull":
        pull = d.values - V.rolling_resistance * d.normal_load
        d = SlipData(slip=d.slip, drawbar_pull=pull, normal_load=d.normal_load, force_std=d.force_std, source="rig")
    one = fit(d, V)
    assert one.extra["weights_from"] == f"{measured}_std_N" and "lack_of_fit" in one.extra
    r = fit([d, _plate(2)], [V, None], labels=["rig", "plate"])
    own = r.datasets[0]
    assert own["outcome"] == one.outcome == "usable"
    assert list(own["noise_sd"]) == [f"{measured}_N_per_std"]
    cov_one = np.asarray(one.covariance)
    se_one = np.sqrt(np.diag(cov_one))
    for q, (k, edge) in enumerate(zip(KEYS, (1e-3, 180 / math.pi, 1.0))):  # SI -> the report's units
        assert own["soil"][k] == pytest.approx(one.theta[q] * edge, rel=1e-8), k
        assert own["soil_stderr"][k] == pytest.approx(se_one[q] * edge, rel=1e-6), k
        assert r.parameters[k].value == pytest.approx(one.theta[q], rel=1e-8), k
    cov_j = r.covariance_si[:3, :3]
    ratio = cov_j / cov_one
    assert np.allclose(ratio, ratio[0, 0], rtol=1e-6), ratio
    assert 0.9 < ratio[0, 0] < 1.1  # the pooled factor (N / (N - P) over n / (n - 3) and the noise floor)


def test_the_std_column_weighs_the_joint_fit():
    """The same rows with and without the std column: different joint estimates (the weights are used)."""
    rw, ru = (fit([_rig_sweep(12, s), _plate(3)], [V, None]) for s in (True, False))
    assert list(ru.datasets[0]["noise_sd"]) == ["tractive_force_N"]
    for k in KEYS:
        a, b = rw.parameters[k], ru.parameters[k]
        assert abs(a.edge_value - b.edge_value) > 1e-4 * abs(b.edge_value), k
    assert rw.parameters["friction_angle_deg"].edge_stderr != pytest.approx(
        ru.parameters["friction_angle_deg"].edge_stderr, rel=1e-3
    )


@pytest.mark.parametrize("effect", ["slip_sinkage", "bulldozing"])
def test_effects_with_a_track_data_set_are_refused_naming_it(effect):
    with pytest.raises(DataError, match=rf"effect\(s\) '{effect}' with the track sweep 'rig'"):
        fit([_rig_sweep(13), _shear(1)], [V, None], labels=["rig", "shear"], effects=[effect])


def test_effects_with_a_drive_log_are_refused_naming_it():
    from soiltrack.soilmodel import DriveLog

    t = np.arange(20) * 0.1
    dl = DriveLog(time=t, sprocket_torque=np.ones(20), sprocket_speed=np.ones(20), vehicle_speed=np.full(20, 0.05))
    with pytest.raises(DataError, match=r"effect\(s\) 'grade' with the drive log 'log'"):
        fit([_shear(1), dl], [None, V], labels=["shear", "log"], effects=["grade"])


def test_cli_joint_fit_refuses_an_effect_with_a_track_file(tmp_path, capsys):
    from soiltrack.soilmodel import write_csv

    a, b = tmp_path / "rig.csv", tmp_path / "shear.csv"
    write_csv(_rig_sweep(14), a)
    write_csv(_shear(2), b)
    assert main(["fit", str(a), str(b), "--vehicle", "light", "--effect", "bulldozing"]) == 2
    err = capsys.readouterr().err
    assert "'bulldozing' with the track sweep" in err and "rig.csv" in err and "Traceback" not in err
