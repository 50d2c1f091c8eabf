"""Rig sweeps as rigs record them: a measured load per row, std weights, repeats, skid and slip-angle rows.

The sweeps are simulated here in plain numpy (Eq. 2 written out again, not soilmodel): a small
rig track (l = 0.0535 m, b = 0.025 m, like a 58 mm wheel approximated as two tracks) whose
measured load varies from row to row, three repeats at each slip level.
"""

import json
import math

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.soilmodel import DataError, SlipData, Vehicle, read_csv

L, B = 0.0535, 0.025
RIG = Vehicle(
    mass=2.5,
    track_length=L,
    track_width=B,
    sprocket_radius=0.058,
    sprocket_inertia=0.001,
    rolling_resistance=0.0,
    name="rig track",
)
SOIL = {"c": 800.0, "phi": math.radians(30.0), "K": 0.01}
SLIP_LEVELS = (0.1, 0.23, 0.5, 0.75, 0.9)


def thrust(i, W, c=SOIL["c"], phi=SOIL["phi"], K=SOIL["K"]):
    """Eq. 2, both tracks (plain numpy)."""
    x = np.maximum(i, 1e-12) * L / K
    return (2 * B * L * c + W * np.tan(phi)) * (1 - (1 - np.exp(-x)) / x)


def rig_rows(seed, levels=SLIP_LEVELS, repeats=3, noise=0.05, mu=0.0, hump=0.0):
    """``slip, drawbar pull, std, load`` of a sweep; ``hump`` > 0 makes the pull fall at high slip."""
    rng = np.random.default_rng(seed)
    i = np.repeat(levels, repeats).astype(float)
    W = rng.uniform(21.0, 27.0, i.size)
    DP = thrust(i, W) * (1 - hump * i**2) - mu * W
    return i, DP + rng.normal(0.0, noise, i.size), np.full(i.size, noise), W


def write(path, cols: dict):
    names = list(cols)
    np.savetxt(path, np.column_stack([cols[n] for n in names]), delimiter=",", header=",".join(names), comments="")
    return str(path)


def test_a_13_row_measured_sweep_reports_by_load_range_in_at_most_80_lines(tmp_path):
    i, DP, std, W = rig_rows(1, levels=(0.1, 0.23, 0.5, 0.9), repeats=3)
    i, DP, std, W = (np.append(a, b) for a, b in zip((i, DP, std, W), (0.0, 0.02, 0.05, 24.0)))
    assert i.size == 13 and np.unique(W).size == 13
    data = read_csv(
        write(tmp_path / "s.csv", {"slip": i, "drawbar_pull_N": DP, "drawbar_pull_std_N": std, "normal_load_N": W})
    )
    r = fit(data, RIG)
    lines = r.report().splitlines()
    assert len(lines) <= 80
    per_load = [ln for ln in lines if ln.lstrip().startswith("F_max at W")]
    assert len(per_load) == 3  # the lowest, the median and the highest load
    assert sum(cb.name.startswith("F_max@W=") for cb in r.combinations) == 13  # every load in the JSON


def test_std_weights_give_noisy_rows_little_say(tmp_path):
    i, DP, std, W = rig_rows(2, noise=0.02)
    bad = np.array([2, 8, 13])  # three rows off by 40 %, and their logged std says they are noisy
    DP[bad] *= 1.4
    std[bad] = 1.0
    cols = {"slip": i, "drawbar_pull_N": DP, "normal_load_N": W}
    plain = fit(read_csv(write(tmp_path / "p.csv", cols)), RIG)
    weighted = fit(read_csv(write(tmp_path / "w.csv", {**cols, "drawbar_pull_std_N": std})), RIG)
    same = fit(SlipData(slip=i, drawbar_pull=DP, normal_load=W), RIG, sigma=std, sigma_known=False)
    true_fmax = 2 * B * L * SOIL["c"] + np.median(W) * math.tan(SOIL["phi"])

    def fmax(res):
        return float(res.predict(np.array([0.999]), normal_load=np.median(W))[0]) / (
            1 - (1 - math.exp(-0.999 * L / res.theta[2])) / (0.999 * L / res.theta[2])
        )

    assert abs(fmax(weighted) / true_fmax - 1) < 0.05
    assert abs(fmax(plain) / true_fmax - 1) > 2 * abs(fmax(weighted) / true_fmax - 1)
    assert np.allclose(weighted.theta, same.theta, rtol=1e-6, atol=1e-9)
    assert weighted.extra["weights_from"] == "drawbar_pull_std_N"


def test_pure_error_test_finds_a_known_lack_of_fit():
    i, DP, _, W = rig_rows(3, hump=0.6, noise=0.03)  # the pull falls at high slip: Eq. 2 cannot follow
    lof = fit(SlipData(slip=i, drawbar_pull=DP, normal_load=W), RIG).extra["lack_of_fit"]
    assert lof["significant"] is True and lof["p_value"] < 1e-3
    assert (lof["levels"], lof["df_lack"], lof["df_pure"]) == (5, 2, 10)


@pytest.mark.slow
def test_pure_error_test_holds_its_level_on_the_model_itself():
    significant = 0
    for seed in range(30):
        i, DP, _, W = rig_rows(100 + seed, noise=0.05)
        significant += fit(SlipData(slip=i, drawbar_pull=DP, normal_load=W), RIG).extra["lack_of_fit"]["significant"]
    assert significant <= 5  # 5 % level: more than 5 of 30 has probability < 0.3 %


def _rows_with_skid_and_angles(tmp_path):
    i, DP, std, W = rig_rows(4, repeats=2)
    i = i.copy()
    i[[0, 3]] = [-0.2, -1.0]  # skid rows 1 and 4
    angle = np.zeros(i.size)
    angle[[5, 6, 9]] = [15.0, 45.0, 90.0]  # rows 6, 7, 10 at a slip angle
    return write(tmp_path / "r.csv", {"slip": i, "drawbar_pull_N": DP, "normal_load_N": W, "slip_angle_deg": angle})


def test_skid_and_slip_angle_rows_are_refused_with_their_rows_named(tmp_path):
    path = _rows_with_skid_and_angles(tmp_path)
    with pytest.raises(DataError) as e:
        read_csv(path)
    assert e.value.rows == (1, 4, 6, 7, 10) and e.value.row == 1 and e.value.column == "slip"
    assert main(["fit", path, "--vehicle", "light"]) == 2
    with pytest.raises(DataError) as e:
        read_csv(path, driving_only=True)
    assert e.value.rows == (6, 7, 10) and e.value.column == "slip_angle_deg"


def test_many_refused_rows_are_counted_and_the_first_named(tmp_path):
    i, DP, _, W = rig_rows(5, repeats=6)
    i[:25] = -0.3
    with pytest.raises(DataError) as e:
        SlipData(slip=i, drawbar_pull=DP, normal_load=W)
    assert e.value.rows == tuple(range(1, 26))


def test_the_options_drop_skid_and_slip_angle_rows_and_count_them(tmp_path, capsys):
    path = _rows_with_skid_and_angles(tmp_path)
    data = read_csv(path, driving_only=True, slip_angle=0.0)
    assert data.n_samples == 5 and data.dropped_count == 5
    assert main(["fit", path, "--vehicle", "light", "--driving-only", "--slip-angle", "0", "--json"]) in (0, 1)
    js = json.loads(capsys.readouterr().out)
    assert {d["option"]: d["count"] for d in js["extra"]["dropped_rows"]} == {"--slip-angle": 3, "--driving-only": 2}
    assert {d["option"]: d["rows"] for d in js["extra"]["dropped_rows"]} == {
        "--slip-angle": [6, 7, 10],
        "--driving-only": [1, 4],
    }
    assert main(["fit", path, "--vehicle", "light", "--slip-angle", "15"]) == 2


@pytest.mark.parametrize("channel", ["drawbar_pull", "tractive_force"])
def test_predict_gives_the_datas_channel_per_row(channel):
    i, DP, _, W = rig_rows(6)
    data = SlipData(slip=i, normal_load=W, **{channel: DP})
    r = fit(data, RIG)
    assert np.allclose(r.predict(data), data.values + r.residuals, rtol=0, atol=1e-9)
    held = SlipData(slip=i[::2] + 0.01, normal_load=W[::2] * 1.1, **{channel: DP[::2]})
    assert np.allclose(r.predict(held), r.predict(held.slip, normal_load=held.normal_load), rtol=0, atol=1e-12)
    with pytest.raises(DataError):
        r.predict(data, normal_load=20.0)


def test_resistance_fit_recovers_the_coefficient_and_the_default_says_it_is_assumed():
    mu = 0.08
    i, DP, _, W = rig_rows(7, levels=(0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 0.9), mu=mu, noise=0.03)
    data = SlipData(slip=i, drawbar_pull=DP, normal_load=W)
    res = fit(data, RIG, resistance="fit").extra["resistance"]
    lo, hi = res["ci95"]
    assert res["mode"] == "fit" and lo <= mu <= hi and hi - lo < 0.1
    assert fit(data, RIG).extra["resistance"] == {
        **fit(data, RIG).extra["resistance"],
        "mode": "assumed",
        "coefficient": 0.0,
    }
    with pytest.raises(DataError):
        fit(SlipData(slip=i, tractive_force=DP, normal_load=W), RIG, resistance="fit")


def test_a_measured_load_that_barely_spreads_says_the_separation_rests_on_it():
    i, DP, _, W = rig_rows(8)
    r = fit(SlipData(slip=i, drawbar_pull=DP, normal_load=W), RIG)
    sep = r.extra["load_separation"]
    assert sep["fragile"] is True and sep["spread"] < 0.3
    assert r.replaced_intervals and {"cohesion", "friction_angle"} <= set(r.replaced_intervals)


def test_resistance_proportional_to_the_sinkage_is_fitted_and_predicts_pulls_with_their_sinkage():
    k_z = 3.0  # 1/m: R / W = 0.045 to 0.075 over 15-25 mm
    i, DP, _, W = rig_rows(9, levels=(0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 0.9), noise=0.03)
    z = 0.015 + 0.01 * i + np.random.default_rng(9).normal(0.0, 0.0005, i.size)
    DP = DP - k_z * z * W
    data = SlipData(slip=i, drawbar_pull=DP, normal_load=W, sinkage=z)
    r = fit(data, RIG, resistance="fit-sinkage")
    res = r.extra["resistance"]
    lo, hi = res["ci95"]
    assert res["mode"] == "fit-sinkage" and lo <= k_z <= hi
    assert r.measured == "drawbar_pull"
    assert np.allclose(r.predict(data), data.values + r.residuals, rtol=0, atol=1e-9)
    with pytest.raises(DataError):  # a pull without its sinkage cannot be predicted
        r.predict(SlipData(slip=i, drawbar_pull=DP, normal_load=W))
    with pytest.raises(DataError):
        fit(SlipData(slip=i, drawbar_pull=DP, normal_load=W), RIG, resistance="fit-sinkage")


def test_cli_resistance_option_exit_codes(tmp_path, capsys):
    i, DP, std, W = rig_rows(10, mu=0.05)
    pull = write(tmp_path / "dp.csv", {"slip": i, "drawbar_pull_N": DP, "normal_load_N": W})
    force = write(tmp_path / "tf.csv", {"slip": i, "tractive_force_N": DP, "normal_load_N": W})
    rig = tmp_path / "rig.json"
    rig.write_text(
        json.dumps(
            {
                "mass_kg": 2.5,
                "track_length_m": L,
                "track_width_m": B,
                "sprocket_radius_m": 0.058,
                "sprocket_inertia_kg_m2": 0.001,
                "rolling_resistance": 0.0,
            }
        )
    )
    assert main(["fit", pull, "--vehicle", str(rig), "--resistance", "fit", "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["extra"]["resistance"]["mode"] == "fit"
    assert main(["fit", force, "--vehicle", str(rig), "--resistance", "fit"]) == 2
    assert main(["fit", pull, "--vehicle", str(rig), "--resistance", "fit-sinkage"]) == 2  # no sinkage_m


def test_the_figure_of_a_measured_load_is_written_and_its_curve_stays_below_full_slip(tmp_path):
    from soiltrack.plots import CURVE_SLIP_END, plot_fit, slip_grid_end

    i, DP, _, W = rig_rows(11)
    data = SlipData(slip=i, drawbar_pull=DP, normal_load=W)
    path = plot_fit(data, RIG, fit(data, RIG), str(tmp_path / "f.png"))
    assert (tmp_path / "f.png").stat().st_size > 10_000 and path.endswith("f.png")
    assert slip_grid_end(i) == CURVE_SLIP_END < 1.0


def test_diagnose_refuses_skid_and_slip_angle_rows_too(tmp_path):
    path = _rows_with_skid_and_angles(tmp_path)
    assert main(["diagnose", path, "--vehicle", "light"]) == 2
    assert main(["diagnose", path, "--vehicle", "light", "--driving-only"]) == 2  # the slip-angle rows remain


def test_std_columns_are_checked(tmp_path):
    i, DP, std, W = rig_rows(12)
    std[[2, 5]] = 0.0
    with pytest.raises(DataError) as e:
        read_csv(write(tmp_path / "z.csv", {"slip": i, "drawbar_pull_N": DP, "drawbar_pull_std_N": std}))
    assert (e.value.column, e.value.rows) == ("drawbar_pull_std_N", (3, 6))
    with pytest.raises(DataError) as e:
        read_csv(write(tmp_path / "o.csv", {"slip": i, "tractive_force_N": DP, "drawbar_pull_std_N": std + 1}))
    assert e.value.column == "drawbar_pull_std_N"


def test_fit_many_takes_the_rig_path_for_rig_sweeps():
    from soiltrack.identify import fit_many

    i, DP, std, W = rig_rows(13)
    data = SlipData(slip=i, drawbar_pull=DP, normal_load=W, force_std=std)
    (one,) = fit_many([data], RIG)
    assert np.allclose(one.theta, fit(data, RIG).theta, rtol=1e-6, atol=1e-9)
    assert one.extra["weights_from"] == "drawbar_pull_std_N" and "lack_of_fit" in one.extra


def _sunk(seed, loads, s_exp=1.0, n=0.8, k=1.5e6):
    """Rows whose sinkage follows Bekker's static sinkage times Lyasko's factor to the power s_exp (numpy)."""
    rng = np.random.default_rng(seed)
    i = np.tile(np.array([0.05, 0.1, 0.2, 0.35, 0.5, 0.7]), len(loads))
    W = np.repeat(np.asarray(loads, dtype=float), 6)
    z = (W / (2 * B * L * k)) ** (1 / n) * ((1 + i) / (1 - 0.5 * i)) ** s_exp
    z = z * np.exp(rng.normal(0, 0.02, i.size))
    return SlipData(slip=i, drawbar_pull=thrust(i, W), normal_load=W, sinkage=z)


def test_the_sinkage_channel_recovers_bekker_n_and_k_and_tests_lyasko():
    from soiltrack.identify.sweep.sinkage_channel import fit_sinkage_channel

    out = fit_sinkage_channel(_sunk(1, (15.0, 25.0, 40.0)), RIG).to_dict()
    assert out["converged"] and out["identifiable"] == ["z0", "bekker_n", "bekker_k_eq", "slip_sinkage_exponent"]
    n, k = out["parameters"]["bekker_n"], out["parameters"]["bekker_k_eq"]
    assert n["ci95"][0] <= 0.8 <= n["ci95"][1] and k["ci95"][0] <= 1.5e3 <= k["ci95"][1]
    s = out["parameters"]["slip_sinkage_exponent"]
    assert s["ci95"][0] <= 1.0 <= s["ci95"][1]
    slow = fit_sinkage_channel(_sunk(2, (15.0, 25.0, 40.0), s_exp=0.4), RIG)
    assert slow.p_lyasko < 1e-3
    one = fit_sinkage_channel(_sunk(3, (25.0,)), RIG).to_dict()
    assert one["identifiable"] == ["z0", "slip_sinkage_exponent"]
    assert one["parameters"]["bekker_n"]["value"] is None and one["parameters"]["bekker_k_eq"]["value"] is None
    z0 = (25.0 / (2 * B * L * 1.5e6)) ** (1 / 0.8)
    assert one["z0_ci95_m"][0] <= z0 <= one["z0_ci95_m"][1]
