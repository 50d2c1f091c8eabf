"""Several data sets on one soil: the joint fit and its consistency test (identify.datasets, fit A B ...).

The data are simulated by the independent numpy oracle (tests/wheel_oracle.py) and a Janosi-Hanamoto
shear test written out here; the truth must lie inside the joint fit's 95 % intervals.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import wheel_oracle as oracle
from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.soilmodel import DataError, ShearTest
from soiltrack.soilmodel.rigid_wheel import RigidWheel
from soiltrack.soilmodel.vehicle import Vehicle
from soiltrack.soilmodel.wheel_sweep import WheelSweep

C, PHI, K, KC, KPHI, N = 2000.0, math.radians(30.0), 0.015, 20e3, 1.2e6, 1.1
WA, WB = RigidWheel(radius=0.15, width=0.08), RigidWheel(radius=0.2, width=0.15)
SLIPS, LOADS = [0.05, 0.15, 0.3, 0.5, 0.7], [60.0, 100.0]


def _sweep(wheel: RigidWheel, seed: int, phi: float = PHI) -> WheelSweep:
    b = wheel.width
    s, dp, W, z = oracle.sweep(
        SLIPS, LOADS, C, phi, K, KC / b + KPHI, N, wheel.radius, b, sd_dp=0.3, sd_z=3e-4, seed=seed
    )
    return WheelSweep(slip=s, drawbar_pull=dp, normal_load=W, sinkage=z, source=f"wheel b={b:g} seed {seed}")


def _shear(seed: int) -> ShearTest:
    rng = np.random.default_rng(seed)
    sig = np.repeat([10e3, 20e3, 30e3], 10)
    j = np.tile(np.linspace(0.002, 0.08, 10), 3)
    tau = (C + sig * math.tan(PHI)) * -np.expm1(-j / K) + rng.normal(0, 100, sig.size)
    return ShearTest(normal_pressure=sig, shear_displacement=j, shear_stress=tau, source="shear")


@pytest.fixture(scope="module")
def consistent():
    return fit([_sweep(WA, 1), _sweep(WB, 2)], [WA, WB], labels=["A", "B"])


@pytest.fixture(scope="module")
def disagreeing():
    return fit([_sweep(WA, 1), _sweep(WB, 3, phi=math.radians(36.0))], [WA, WB], labels=["A", "Bbad"])


def _write(path, name: str, wheel: RigidWheel, data: WheelSweep) -> tuple[str, str]:
    csv = path / f"{name}.csv"
    rows = ["slip,drawbar_pull_N,normal_load_N,sinkage_m"]
    rows += [
        f"{a:.8g},{b:.8g},{c:.8g},{d:.8g}"
        for a, b, c, d in zip(data.slip, data.drawbar_pull, data.normal_load, data.sinkage)
    ]
    csv.write_text("\n".join(rows) + "\n")
    js = path / f"w{wheel.width:g}.json"
    js.write_text(
        json.dumps({"running_gear": "rigid_wheel", "wheel_radius_m": wheel.radius, "wheel_width_m": wheel.width})
    )
    return str(csv), str(js)


@pytest.mark.slow
def test_two_wheels_of_one_soil_are_consistent_and_hold_the_truth(consistent):
    r = consistent
    assert r.outcome == "usable", r.fit_outcome.reason
    c = r.consistency
    assert c["dof"] == 4  # each wheel: 5 directions (k_c and k_phi only as k_c / b + k_phi), joint 6
    assert c["p_value"] > 0.01 and not c["poor_fit"] and c["disagrees"] is None
    truth = {
        "cohesion_kpa": C / 1e3,
        "friction_angle_deg": math.degrees(PHI),
        "shear_modulus_m": K,
        "bekker_kc": KC / 1e3,
        "bekker_kphi": KPHI / 1e3,
        "bekker_n": N,
    }
    for key, v in truth.items():
        e = r.parameters[key]
        assert e.identifiable and e.edge_ci95[0] <= v <= e.edge_ci95[1], (key, e.edge_ci95, v)
    # two widths separate k_c from k_phi; each wheel alone does not
    assert all(d["soil"]["bekker_kc"] is None for d in r.datasets)
    assert len(c["shifts_se"]["friction_angle_deg"]) == 2
    assert all(abs(s) < 3 for s in c["shifts_se"]["friction_angle_deg"])


@pytest.mark.slow
def test_two_soils_are_a_poor_fit_naming_the_data_set(disagreeing):
    r = disagreeing
    assert r.outcome == "poor_fit"
    c = r.consistency
    assert c["poor_fit"] and c["p_value"] < 1e-4
    assert c["disagrees"] == "Bbad"
    assert "Bbad" in r.fit_outcome.reason
    assert c["contributions"][1] > c["contributions"][0]
    assert r.report().splitlines()[0].startswith("outcome: POOR_FIT")
    assert "consistency of one soil" in r.report().splitlines()[2]


@pytest.mark.slow
def test_a_wheel_with_a_shear_test_shares_the_soil():
    r = fit([_sweep(WA, 1), _shear(5)], [WA, None], labels=["wheel", "shear"])
    assert r.outcome == "usable"
    assert r.consistency["dof"] == 3  # the shear test's c, phi, K shared with the wheel
    for key, v in (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K)):
        e = r.parameters[key]
        assert e.edge_ci95[0] <= v <= e.edge_ci95[1], (key, e.edge_ci95, v)
    assert r.datasets[1]["kind"] == "shear_test"
    # the shear test narrows the joint friction angle against the wheel's own
    own = r.datasets[0]["soil_stderr"]["friction_angle_deg"]
    assert r.parameters["friction_angle_deg"].edge_stderr < own


@pytest.mark.slow
def test_cli_joint_fit_exit_codes_and_json(tmp_path, capsys):
    a_csv, a_js = _write(tmp_path, "a", WA, _sweep(WA, 1))
    b_csv, b_js = _write(tmp_path, "b", WB, _sweep(WB, 2))
    bad_csv, _ = _write(tmp_path, "bad", WB, _sweep(WB, 3, phi=math.radians(36.0)))
    assert main(["fit", a_csv, b_csv, "--vehicle", a_js, "--vehicle", b_js, "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["outcome"] == "usable" and js["kind"] == "joint"
    assert set(js["consistency"]) >= {"p_value", "test", "shifts_se", "dof", "statistic"}
    assert [d["file"] for d in js["datasets"]] == [a_csv, b_csv]
    assert all(d["rows"] == 10 and d["gear"]["kind"] == "rigid_wheel" for d in js["datasets"])
    assert main(["fit", a_csv, bad_csv, "--vehicle", a_js, "--vehicle", b_js]) == 1
    out = capsys.readouterr().out
    assert out.startswith("outcome: POOR_FIT") and bad_csv in out.splitlines()[0]


def test_cli_vehicle_count_neither_one_nor_per_file_exits_2(tmp_path, capsys):
    files = []
    for k in range(3):
        p = tmp_path / f"f{k}.csv"
        p.write_text("slip,drawbar_pull_N,normal_load_N\n0.1,1,50\n0.2,2,50\n")
        files.append(str(p))
    js = tmp_path / "w.json"
    js.write_text(json.dumps({"running_gear": "rigid_wheel", "wheel_radius_m": 0.1, "wheel_width_m": 0.05}))
    assert main(["fit", *files, "--vehicle", str(js), "--vehicle", str(js)]) == 2
    err = capsys.readouterr().err
    assert "--vehicle" in err and "3 files" in err and "got 2" in err and "Traceback" not in err
    assert main(["fit", files[0], "--vehicle", str(js), "--vehicle", str(js)]) == 2
    assert "once" in capsys.readouterr().err
    assert main(["fit", *files[:2], "--vehicle", str(js), "--plot", str(tmp_path / "x.png")]) == 2
    assert main(["fit", files[0], "--vehicle", str(js), "--fit-grouser-height"]) == 2
    assert "needs several files" in capsys.readouterr().err
    assert main(["fit", *files[:2], "--vehicle", str(js), "--fit-grouser-height"]) == 2
    assert "grouser_height_m > 0" in capsys.readouterr().err


def test_python_joint_fit_bad_input():
    s = _shear(1)
    with pytest.raises(DataError, match="at least two"):
        fit([s], None)
    with pytest.raises(DataError, match="one per data set"):
        fit([s, s, s], [None, None])
    veh = Vehicle(
        mass=1000.0,
        track_length=2.0,
        track_width=0.4,
        sprocket_radius=0.3,
        sprocket_inertia=1.0,
        rolling_resistance=0.05,
    )
    w = WheelSweep(slip=np.array([0.1, 0.2, 0.3]), drawbar_pull=np.ones(3), normal_load=np.full(3, 50.0))
    with pytest.raises(DataError, match="needs a RigidWheel"):
        fit([w, s], veh)
    with pytest.raises(DataError, match="needs a RigidWheel"):
        fit([w, s], None)
    with pytest.raises(DataError, match="do not apply"):
        fit([s, s], None, sigma=1.0)


@pytest.mark.slow
def test_a_grousered_wheels_height_is_fitted_beside_a_smooth_wheel():
    """One soil, a smooth and a grousered wheel: the grouser height (gear-specific) is fitted; held at 0 the
    grousered wheel disagrees."""
    smooth = RigidWheel(radius=0.15, width=0.08)
    h = 0.012
    s, dp, W, z = oracle.sweep(
        SLIPS, LOADS, C, PHI, K, KC / 0.08 + KPHI, N, 0.15, 0.08, h=h, sd_dp=0.3, sd_z=3e-4, seed=2
    )
    g = WheelSweep(slip=s, drawbar_pull=dp, normal_load=W, sinkage=z)
    a = _sweep(smooth, 1)
    r = fit([a, g], [smooth, RigidWheel(0.15, 0.08, grouser_height=0.006)], labels=["smooth", "g"], free_grousers=[1])
    assert r.outcome == "usable"
    e = r.specific[1]["grouser_height_m"]
    assert e.identifiable and e.edge_ci95[0] <= h <= e.edge_ci95[1], e.edge_ci95
    assert r.specific[0] == {}
    for key, v in (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K)):
        assert r.parameters[key].edge_ci95[0] <= v <= r.parameters[key].edge_ci95[1], key
    # alone, the grousered wheel's c and phi are confounded with its grouser height
    assert r.datasets[1]["soil"]["cohesion_kpa"] is None
    held = fit([a, g], [smooth, RigidWheel(0.15, 0.08)], labels=["smooth", "g as smooth"])
    assert held.outcome == "poor_fit" and held.consistency["disagrees"] == "g as smooth"
    with pytest.raises(DataError, match="free_grousers"):
        fit([a, _shear(1)], [smooth, None], free_grousers=[1])


@pytest.mark.slow
def test_a_wheel_with_a_plate_test_shares_the_bekker_soil():
    from soiltrack.soilmodel import PlateTest

    rng = np.random.default_rng(3)
    b = np.repeat([0.05, 0.1], 8)
    z = np.tile(np.linspace(0.005, 0.04, 8), 2)
    p = (KC / b + KPHI) * z**N
    plate = PlateTest(plate_width=b, pressure=p + rng.normal(0, 0.01 * p.max(), p.size), sinkage=z, source="plate")
    r = fit([_sweep(WA, 1), plate], [WA, None], labels=["wheel", "plate"])
    assert r.outcome == "usable" and r.consistency["dof"] == 2  # wheel rank 5 + plate 3 - joint 6
    for key, v in (("bekker_kc", KC / 1e3), ("bekker_kphi", KPHI / 1e3), ("bekker_n", N)):
        e = r.parameters[key]
        assert e.edge_ci95[0] <= v <= e.edge_ci95[1], (key, e.edge_ci95, v)
    assert r.datasets[1]["kind"] == "plate_test" and "cohesion_kpa" not in r.datasets[1]["soil"]


def _annulus_torque(theta, sigma, r_i=0.15, r_o=0.2):
    """Closed form of 2 pi int r^2 (c + sigma tan phi)(1 - exp(-r theta / K)) dr (written out here)."""
    a = theta / K

    def prim(r):  # int r^2 exp(-a r) dr
        return -np.exp(-a * r) * (r**2 / a + 2 * r / a**2 + 2 / a**3)

    return 2 * math.pi * (C + sigma * math.tan(PHI)) * ((r_o**3 - r_i**3) / 3 - (prim(r_o) - prim(r_i)))


@pytest.mark.slow
def test_a_shear_test_and_a_shear_annulus_share_c_phi_k():
    from soiltrack.soilmodel.bevameter_records import AnnulusTest

    rng = np.random.default_rng(11)
    sig = np.repeat([10e3, 20e3, 30e3], 8)
    th = np.tile(np.radians(np.linspace(1.0, 40.0, 8)), 3)
    T = np.array([_annulus_torque(t, s) for t, s in zip(th, sig)])
    ring = AnnulusTest(
        normal_pressure=sig,
        rotation=th,
        torque=T + rng.normal(0, 0.5, T.size),
        inner_radius=np.full(T.size, 0.15),
        outer_radius=np.full(T.size, 0.2),
        source="annulus",
    )
    r = fit([_shear(5), ring], None, labels=["shear", "annulus"])
    assert r.outcome == "usable" and r.consistency["dof"] == 3 and r.consistency["p_value"] > 0.01
    assert r.datasets[1]["kind"] == "shear_annulus"
    for key, v in (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K)):
        e = r.parameters[key]
        assert e.edge_ci95[0] <= v <= e.edge_ci95[1], (key, e.edge_ci95, v)
    assert r.parameters["bekker_n"].fixed  # no data set sees the Bekker soil: held, said so
