"""The sinkage channel of a track sweep: Bekker n, k_c / b + k_phi and slip sinkage from ``sinkage_m``.

Sinkage rows are made here in plain numpy from the textbook formulas (Bekker's static sinkage
``z0 = (W / (2 b l k)) ^ (1 / n)``, Lyasko's factor ``(1 + i) / (1 - 0.5 i)``), independent of
soilmodel, with multiplicative (log-normal) reading errors; the slip-sinkage evidence is also
checked on soilmodel's own simulator.
"""

import json
import math

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.identify.sweep.sinkage_channel import (
    SLIP_SINKAGE_ALPHA,
    fit_sinkage_channel,
    slip_sinkage_evidence,
)
from soiltrack.soilmodel import TERRAINS, VEHICLES, SlipData, Vehicle
from soiltrack.soilmodel.simulation import simulate_slip_sweep

L, B = 0.5, 0.1
TRACK = Vehicle(
    mass=30.0, track_length=L, track_width=B, sprocket_radius=0.08, sprocket_inertia=0.05, rolling_resistance=0.05
)
N_TRUE, KC_TRUE, KPHI_TRUE = 0.7, 5.27e3, 1515.04e3  # sandy loam (SI)
K_TRUE = KC_TRUE / B + KPHI_TRUE
SLIPS = np.array([0.03, 0.08, 0.15, 0.25, 0.4, 0.55, 0.7])


def textbook_rows(seed, loads, s_exp=1.0, rel=0.03, n=N_TRUE, k=K_TRUE, slips=SLIPS):
    """Slip, load, sinkage: Bekker's static sinkage times Lyasko's factor ** s_exp, log-normal errors."""
    rng = np.random.default_rng(seed)
    i = np.tile(slips, len(loads))
    W = np.repeat(np.asarray(loads, dtype=float), slips.size)
    z = (W / (2 * B * L * k)) ** (1 / n) * ((1 + i) / (1 - 0.5 * i)) ** s_exp
    return i, W, z * np.exp(rng.normal(0.0, rel, i.size))


def sweep(i, W, z):
    return SlipData(slip=i, drawbar_pull=np.full(i.shape, 100.0), normal_load=W, sinkage=z)


def test_n_and_k_are_recovered_with_intervals_that_cover_the_truth():
    ch = fit_sinkage_channel(sweep(*textbook_rows(1, (200.0, 300.0, 450.0))), TRACK)
    assert ch.converged and ch.n_identifiable
    n, k = ch.parameters["bekker_n"], ch.parameters["bekker_k_eq"]
    assert abs(n.value / N_TRUE - 1) < 0.1 and abs(k.value / K_TRUE - 1) < 0.3
    assert n.ci95[0] <= N_TRUE <= n.ci95[1] and k.ci95[0] <= K_TRUE <= k.ci95[1]
    # the fitted laws' sinkage is the textbook formula at the reported n, k and s
    s = ch.parameters["slip_sinkage_exponent"].value
    i, W = np.array([0.0, 0.2, 0.6]), np.array([200.0, 300.0, 450.0])
    textbook = (W / (2 * B * L * k.value)) ** (1 / n.value) * ((1 + i) / (1 - 0.5 * i)) ** s
    assert np.allclose(ch.predict(i, W), textbook, rtol=1e-9)
    # k_c and k_phi never separate at one track width
    assert not ch.parameters["bekker_kc"].identifiable and ch.parameters["bekker_kc"].value is None
    assert not ch.parameters["bekker_kphi"].identifiable and ch.parameters["bekker_kphi"].value is None


def test_the_intervals_cover_n_k_and_the_slip_exponent_about_95_percent_of_the_time():
    hits = {"bekker_n": 0, "bekker_k_eq": 0, "slip_sinkage_exponent": 0}
    truth = {"bekker_n": N_TRUE, "bekker_k_eq": K_TRUE, "slip_sinkage_exponent": 1.0}
    runs = 60
    for seed in range(runs):
        ch = fit_sinkage_channel(sweep(*textbook_rows(100 + seed, (220.0, 300.0, 400.0), rel=0.05)), TRACK)
        for key in hits:
            lo, hi = ch.parameters[key].ci95
            hits[key] += int(lo is not None and hi is not None and lo <= truth[key] <= hi)
    # Binomial(60, 0.95): P(X <= 52) is about 1 %
    assert all(h >= 53 for h in hits.values()), hits
    assert all(h <= runs for h in hits.values())


def test_one_load_identifies_only_the_static_sinkage_there():
    i, W, z = textbook_rows(3, (300.0,))
    ch = fit_sinkage_channel(sweep(i, W, z), TRACK)
    assert ch.converged and not ch.n_identifiable
    for key in ("bekker_n", "bekker_k_eq", "bekker_kc", "bekker_kphi"):
        p = ch.parameters[key]
        assert not p.identifiable and p.value is None and p.ci95 == (None, None)
    z0 = (300.0 / (2 * B * L * K_TRUE)) ** (1 / N_TRUE)
    assert ch.z0_ci95[0] <= z0 <= ch.z0_ci95[1] and abs(ch.z0 / z0 - 1) < 0.05
    assert ch.parameters["slip_sinkage_exponent"].identifiable


def test_loads_that_barely_spread_leave_n_not_identifiable():
    i, W, z = textbook_rows(4, (299.0, 300.0, 301.0), rel=0.05)
    ch = fit_sinkage_channel(sweep(i, W, z), TRACK)
    assert ch.converged and ch.free[1] and not ch.n_identifiable
    assert ch.parameters["bekker_n"].value is None and ch.parameters["bekker_k_eq"].ci95 == (None, None)


def test_evidence_of_slip_sinkage_found_when_present_and_not_when_absent():
    found_present, found_absent, lyasko_refuted = 0, 0, 0
    for seed in range(20):
        present = slip_sinkage_evidence(sweep(*textbook_rows(seed, (250.0, 350.0), s_exp=1.0)), TRACK)
        absent = slip_sinkage_evidence(sweep(*textbook_rows(seed, (250.0, 350.0), s_exp=0.0)), TRACK)
        assert present.testable and absent.testable and present.n_rows == 14 and present.dof == 11
        found_present += present.found()
        found_absent += absent.found()
        lyasko_refuted += present.p_lyasko < SLIP_SINKAGE_ALPHA
        assert absent.p_lyasko < 1e-6  # no slip sinkage: Lyasko's law refuted
    assert found_present == 20 and found_absent <= 3 and lyasko_refuted <= 3


def test_a_load_that_falls_as_the_slip_rises_does_not_pass_for_slip_sinkage():
    # the measured rig's pattern: the lowest loads at the highest slips; no slip sinkage
    rng = np.random.default_rng(7)
    i = np.repeat(SLIPS, 3)
    W = 400.0 - 300.0 * i + rng.normal(0.0, 10.0, i.size)
    z = (W / (2 * B * L * K_TRUE)) ** (1 / N_TRUE) * np.exp(rng.normal(0.0, 0.03, i.size))
    ev = slip_sinkage_evidence(sweep(i, W, z), TRACK)
    assert ev.testable and not ev.found() and ev.p_no_slip_sinkage > SLIP_SINKAGE_ALPHA
    assert abs(np.corrcoef(z, i)[0, 1]) > 0.8  # while the raw sinkage falls with the slip


def test_evidence_on_soilmodels_simulator_with_and_without_slip_sinkage():
    v, soil = VEHICLES["light"], TERRAINS["sandy_loam"]
    loads = (250.0, 300.0, 400.0)
    with_it = simulate_slip_sweep(v, soil, normal_loads=loads, seed=5, sinkage_slip_exponent=1.0)
    without = simulate_slip_sweep(v, soil, normal_loads=loads, seed=5, sinkage_slip_exponent=0.0)
    ev1, ev0 = slip_sinkage_evidence(with_it, v), slip_sinkage_evidence(without, v)
    assert ev1.found() and ev1.p_no_slip_sinkage < 1e-6 and ev1.p_lyasko > SLIP_SINKAGE_ALPHA
    assert not ev0.found() and ev0.p_no_slip_sinkage > SLIP_SINKAGE_ALPHA and ev0.p_lyasko < 1e-6
    # the simulator's sinkage is soilmodel's law: the channel returns the soil's n and k
    ch = fit_sinkage_channel(with_it, v)
    k_true = soil.k_c / v.track_width + soil.k_phi  # SI: the record stores N/m^(n+2)
    assert ch.parameters["bekker_n"].ci95[0] <= soil.n <= ch.parameters["bekker_n"].ci95[1]
    assert ch.parameters["bekker_k_eq"].ci95[0] <= k_true <= ch.parameters["bekker_k_eq"].ci95[1]


def test_no_test_without_a_sinkage_column_or_at_one_slip():
    i, W, z = textbook_rows(6, (300.0,))
    ev = slip_sinkage_evidence(SlipData(slip=i, drawbar_pull=np.ones_like(i), normal_load=W), TRACK)
    assert not ev.testable and ev.exponent is None and ev.p_no_slip_sinkage is None and not ev.found()
    one_slip = textbook_rows(6, (250.0, 300.0, 400.0), slips=np.array([0.2, 0.2]))
    ev = slip_sinkage_evidence(sweep(*one_slip), TRACK)
    assert not ev.testable and ev.n_rows == 6 and not ev.found()
    few = slip_sinkage_evidence(sweep(*textbook_rows(6, (300.0,), slips=np.array([0.1, 0.3, 0.5]))), TRACK)
    assert not few.testable and few.n_rows == 3


def test_a_sweep_without_sinkage_keeps_its_parameters_and_one_with_it_adds_the_sinkage_laws():
    i, W, z = textbook_rows(8, (250.0, 350.0))
    x = i * L / 0.02
    F = (2 * B * L * 1.7e3 + W * math.tan(math.radians(29.0))) * (1 - (1 - np.exp(-x)) / x)
    plain_fit = fit(SlipData(slip=i, tractive_force=F, normal_load=W), TRACK)
    plain = plain_fit.to_dict()
    assert plain_fit.sinkage_parameters == {} and "sinkage_m" not in plain.get("extra", {})
    assert set(plain["parameters"]) == {"cohesion_kpa", "friction_angle_deg", "shear_modulus_m"}
    sunk_fit = fit(SlipData(slip=i, tractive_force=F, normal_load=W, sinkage=z), TRACK)
    sunk = sunk_fit.to_dict()
    assert sunk_fit.sinkage_parameters == {k: sunk["parameters"][k] for k in sunk_fit.sinkage_parameters}
    keys = {"bekker_kc", "bekker_kphi", "bekker_n", "bekker_k_eq", "slip_sinkage_exponent"}
    assert keys <= set(sunk["parameters"])
    n = sunk["parameters"]["bekker_n"]
    assert n["identifiable"] and abs(n["value"] / N_TRUE - 1) < 0.15  # (coverage: the test above)
    assert sunk["parameters"]["bekker_kc"]["identifiable"] is False
    # the soil's parameters are those of the fit without the sinkage
    for key in ("cohesion_kpa", "friction_angle_deg", "shear_modulus_m"):
        assert sunk["parameters"][key]["value"] == pytest.approx(plain["parameters"][key]["value"], rel=1e-9)


def test_cli_json_carries_the_sinkage_parameters(tmp_path, capsys):
    i, W, z = textbook_rows(9, (250.0, 350.0))
    x = i * L / 0.02
    F = (2 * B * L * 1.7e3 + W * math.tan(math.radians(29.0))) * (1 - (1 - np.exp(-x)) / x)
    path = tmp_path / "s.csv"
    np.savetxt(
        path,
        np.column_stack([i, F, W, z]),
        delimiter=",",
        header="slip,tractive_force_N,normal_load_N,sinkage_m",
        comments="",
    )
    veh = tmp_path / "v.json"
    veh.write_text(
        json.dumps(
            {
                "mass_kg": 30.0,
                "track_length_m": L,
                "track_width_m": B,
                "sprocket_radius_m": 0.08,
                "sprocket_inertia_kg_m2": 0.05,
                "rolling_resistance": 0.05,
            }
        )
    )
    assert main(["fit", str(path), "--vehicle", str(veh), "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    for key in ("bekker_n", "bekker_k_eq", "slip_sinkage_exponent"):
        p = js["parameters"][key]
        assert p["identifiable"] is True and p["ci95"][0] < p["value"] < p["ci95"][1]
    assert js["extra"]["sinkage_m"]["laws"]["converged"] is True


def test_the_slip_resistance_of_the_measured_ruts_is_set_beside_the_thrust_fits():
    from soiltrack.identify.sweep.sinkage_channel import compare_slip_resistance

    i, W, z = textbook_rows(11, (250.0, 300.0, 400.0))
    x = i * L / 0.02
    F = (2 * B * L * 1.7e3 + W * math.tan(math.radians(29.0))) * (1 - (1 - np.exp(-x)) / x)
    mu_s = 0.1
    DP = F - 0.05 * W - mu_s * i * W + np.random.default_rng(11).normal(0.0, 0.5, i.size)
    data = SlipData(slip=i, drawbar_pull=DP, normal_load=W, sinkage=z)
    r = fit(data, TRACK, effects=["slip_sinkage"], slip_noise="off")
    eff = r.extra["sinkage_m"]["laws"]["slip_sinkage_effect"]
    # Bekker compaction of the true ruts, textbook numpy: R = 2 b k z^(n+1) / (n+1), slope of dR / W on i
    z0 = (W / (2 * B * L * K_TRUE)) ** (1 / N_TRUE)
    zi = z0 * (1 + i) / (1 - 0.5 * i)
    dR = 2 * B * K_TRUE * (zi ** (N_TRUE + 1) - z0 ** (N_TRUE + 1)) / (N_TRUE + 1)
    mu_ruts = float(np.sum(i * dR / W) / np.sum(i * i))
    lo = eff["mu_s_sinkage"] - 1.96 * eff["mu_s_sinkage_stderr"]
    hi = eff["mu_s_sinkage"] + 1.96 * eff["mu_s_sinkage_stderr"]
    assert lo <= mu_ruts <= hi and mu_ruts < 0.05
    assert abs(eff["mu_s_thrust_fit"] - mu_s) < 0.03
    assert eff["p_agreement"] < 1e-3 and eff["agree"] is False  # a resistance 0.1 i W is not these ruts' compaction
    # at one load the ruts' compaction needs n, which the rows do not give
    one = fit_sinkage_channel(sweep(*textbook_rows(12, (300.0,))), TRACK)
    pe = r.effects["slip_sinkage"]["mu_s"]
    out = compare_slip_resistance(one, sweep(*textbook_rows(12, (300.0,))), TRACK, pe)
    assert out["mu_s_sinkage"] is None and out["p_agreement"] is None and out["agree"] is None


def test_cli_simulates_a_track_sweep_with_its_sinkage(tmp_path, capsys):
    out = tmp_path / "s.csv"
    args = ["simulate", "--kind", "sweep", "--vehicle", "light", "--terrain", "sandy_loam", "--loads", "250,400"]
    assert main([*args, "--sinkage", "lyasko", "--seed", "1", "-o", str(out)]) == 0
    assert out.read_text().splitlines()[0].split(",") == ["slip", "tractive_force_N", "normal_load_N", "sinkage_m"]
    assert main(["fit", str(out), "--vehicle", "light", "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    s = js["parameters"]["slip_sinkage_exponent"]
    assert s["ci95"][0] <= 1.0 <= s["ci95"][1] and js["extra"]["sinkage_m"]["laws"]["p_no_slip_sinkage"] < 1e-6
    # no Bekker parameters with --soil, and no sinkage for a drive log: refused, exit 2
    assert (
        main(["simulate", "--kind", "sweep", "--vehicle", "light", "--soil", "1,30,0.01", "--sinkage", "static"]) == 2
    )
    assert main(["simulate", "--vehicle", "light", "--sinkage", "static", "--seed", "1"]) == 2


def test_a_load_tied_exactly_to_the_slip_identifies_neither_n_nor_the_slip_exponent():
    i = np.repeat(np.array([0.1, 0.5]), 4)
    W = np.where(i < 0.3, 250.0, 400.0)
    z = (W / (2 * B * L * K_TRUE)) ** (1 / N_TRUE) * np.exp(np.random.default_rng(13).normal(0.0, 0.03, i.size))
    ch = fit_sinkage_channel(sweep(i, W, z), TRACK)
    assert ch.converged and ch.free == (True, False, False)
    assert not ch.n_identifiable and not ch.parameters["slip_sinkage_exponent"].identifiable
    ev = slip_sinkage_evidence(sweep(i, W, z), TRACK)
    assert not ev.testable and ev.p_no_slip_sinkage is None and not ev.found()


def test_a_wheel_sweep_is_no_test_of_the_tracks_slip_sinkage():
    from soiltrack.soilmodel.rigid_wheel import RigidWheel
    from soiltrack.soilmodel.wheel_sweep import WheelSweep

    i = np.array([0.1, 0.3, 0.5, 0.7, 0.9])
    data = WheelSweep(slip=i, drawbar_pull=np.ones_like(i), normal_load=np.full(i.shape, 20.0), sinkage=0.01 + 0.01 * i)
    ev = slip_sinkage_evidence(data, RigidWheel(radius=0.058, width=0.05))
    assert not ev.testable and ev.exponent is None and not ev.found()
