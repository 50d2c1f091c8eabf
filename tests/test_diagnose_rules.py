"""Sweeps from independent code: a load cell at its limit is the plateau cause; an effect-free clayey sweep is
none; the plateau and lone-reading tools."""

import pytest

from soiltrack.identify import diagnose
from soiltrack.soilmodel import VEHICLES, SensorNoise
from conftest import independent_check, independent_sweep

HEAVY = VEHICLES["heavy"]
SLIPS = tuple(round(0.01 + k * (0.69 / 59), 4) for k in range(60))
LOW = SensorNoise(force_rel=0.005, slip_abs=0.0005)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_load_cell_flat_at_its_limit_is_unexplained_not_an_effect(tmp_path, seed):
    # a load cell saturating at 80 % of the peak, noise added after the clip (outside the library; independent
    # numpy): 58 of 60 readings flat. Measured before the plateau check: hump_shear 0.50 on all three seeds (seed 1
    # with a held-out shrink of -0.16); the rival rule of test_diagnose.py had capped it at 0.5
    d = diagnose(independent_sweep(tmp_path / "clipped.csv", seed, clip=0.8), HEAVY)
    assert (d.verdict, d.cause) == ("unexplained", "plateau"), (d.verdict, d.cause)
    assert d.cause_detail["level_N"] == pytest.approx(_oracle_clip(0.8), rel=0.005)
    assert d.confidence == pytest.approx(sum(e.weight for e in d.ranking if e.family in ("flexible", "outside")))


def _oracle_clip(share: float) -> float:
    """The clip level of the oracle's sweep: ``share`` of its noise-free drawbar-pull peak (default soil)."""
    import numpy as np

    ic = independent_check()
    i = np.linspace(0.02, 0.7, 60)
    D = ic.thrust_quadrature(i, ic.W0, 1300.0, np.radians(31.1), 0.012) - ic.W0 * ic.MU
    return share * float(D.max())


def test_find_plateau_needs_the_soil_below_to_rise_to_the_level():
    import numpy as np
    from soiltrack.identify.diagnosis.sweep_parts import find_plateau

    slip = np.linspace(0.02, 0.7, 30)
    flat = np.full(30, 100.0) + np.where(np.arange(30) % 2, 1.0, -1.0)
    flat[:2] = [60.0, 90.0]
    sig = np.ones(30)
    p = find_plateau(flat, slip, sig, lambda idx: None)  # two readings below: the soil passes through them
    assert p is not None and len(p.rows) == 28 and p.level == pytest.approx(100.0, abs=0.1)
    assert p.slip_range[0] == pytest.approx(slip[2])
    # a soil fitted below that stays under the level at the plateau's slips: nothing is clipped
    low = flat.copy()
    low[:6] = [40.0, 50.0, 60.0, 70.0, 80.0, 90.0]

    def soil(curve):  # a "fit" below: the given curve's residuals on idx, its predictions on the rest
        return lambda idx: (low[idx] - curve[idx], np.delete(curve, idx))

    k = np.arange(30.0)
    rises = find_plateau(low, slip, sig, soil(40.0 + 10.0 * k))
    assert len(rises.rows) == 24 and float(rises.z @ rises.z) == pytest.approx(24.0)
    stays = find_plateau(low, slip, sig, soil(np.minimum(40.0 + 10.0 * k, 50.0)))
    # only the level through all but the two lowest readings is left, and it fits far worse
    assert len(stays.rows) == 28 and float(stays.z @ stays.z) > 10 * float(rises.z @ rises.z)


@pytest.mark.slow
def test_an_effect_free_clayey_sweep_from_independent_code_is_none(tmp_path):
    # independent oracle, effect-free, c = 4.14 kPa, phi = 13 deg, K = 6 mm, seed 0: white residuals, with a
    # chance lag-1 correlation of 0.26; a 10-knot flexible term wins on all the data
    import numpy as np

    d = diagnose(independent_sweep(tmp_path / "clay.csv", 0, c=4140.0, phi=np.radians(13.0), K=0.006), HEAVY)
    assert d.verdict == "none" and not d.gap.present, [t.to_dict() for t in d.gap.tests]


def test_isolated_outliers_finds_lone_readings_and_spares_noise_steps_and_growth():
    import numpy as np
    from soiltrack.identify.diagnosis.gap import OUTLIER_Z, isolated_outliers

    rng = np.random.default_rng(7)
    x = np.linspace(0.02, 0.7, 60)
    r = rng.normal(0.0, 1.0, 60)
    assert isolated_outliers(r, x) == []
    spiked = r.copy()
    spiked[[17, 41]] += [12.0, -10.0]
    found = isolated_outliers(spiked[::-1], x[::-1])  # in any row order
    assert sorted(59 - k for k, _ in found) == [17, 41] and all(abs(z) > OUTLIER_Z for _, z in found)
    step = r.copy()
    step[30:] += 15.0  # a step (a change of terrain, a sharp bend) is not a lone reading
    assert isolated_outliers(step, x) == []
    pair = r.copy()
    pair[[20, 21]] += 15.0  # two neighbours off together: not isolated
    assert isolated_outliers(pair, x) == []
    grows = rng.normal(0.0, 1.0, 60) * np.linspace(0.2, 3.0, 60)  # noise growing along the sweep
    assert isolated_outliers(grows, x) == []
    # a signal stepping to a limit where its noise grows 20-fold (a torque at its limit): with the sides'
    # noise levels estimated apart, the readings after the step are not lone readings
    limit = np.where(np.arange(60) < 30, 1.0 + 0.05 * rng.normal(size=60), 100.0 + 1.0 * rng.normal(size=60))
    assert isolated_outliers(limit, x, split_sides=True) == []
    glitch = limit.copy()
    glitch[45] += 30.0
    assert [k for k, _ in isolated_outliers(glitch, x, split_sides=True)] == [45]
    # Gaussian noise: no false flag in 500 series of 60
    assert sum(bool(isolated_outliers(rng.normal(size=60), x)) for _ in range(500)) == 0


def test_isolated_outliers_with_trend_finds_a_glitch_on_a_ramp_but_no_step():
    import numpy as np
    from soiltrack.identify.diagnosis.gap import isolated_outliers

    rng = np.random.default_rng(3)
    t = np.arange(200) * 0.05
    ramp = 500.0 * np.arange(200) + rng.normal(0.0, 100.0, 200)  # a torque ramping 5 noise levels per sample
    assert isolated_outliers(ramp, t, trend=True) == []
    spiked = ramp.copy()
    spiked[[60, 140]] += [20000.0, -15000.0]
    # without the trend the neighbours of a glitch on the ramp differ by ten noise levels: "not a lone reading"
    assert isolated_outliers(spiked, t) == []
    assert sorted(k for k, _ in isolated_outliers(spiked, t, trend=True)) == [60, 140]
    step = ramp.copy()
    step[100:] += 5000.0  # a step on the ramp is still not a lone reading
    assert isolated_outliers(step, t, trend=True) == []
    bend = np.where(np.arange(200) < 100, 500.0, -500.0).cumsum() + rng.normal(0.0, 100.0, 200)  # a kink
    assert isolated_outliers(bend, t, trend=True) == []
