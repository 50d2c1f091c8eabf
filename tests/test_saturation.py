"""A clipped sensor is found, and weighed as a cause outside the library beside the effects."""

import dataclasses

import numpy as np
import pytest

from soiltrack.identify import diagnose
from soiltrack.identify.diagnosis.saturation import find_saturation
from soiltrack.soilmodel import TERRAINS, VEHICLES, SensorNoise, SlipData, simulate

VEH = VEHICLES["light"]
SLIPS = np.round(np.linspace(0.01, 0.7, 60), 4)


def _sweep(seed=1):
    return simulate(
        VEH,
        TERRAINS["lete_sand"],
        kind="sweep",
        seed=seed,
        slips=SLIPS,
        noise=SensorNoise(force_rel=0.005, slip_abs=0.0005),
    )


def _clipped(d: SlipData, share: float = 0.85) -> SlipData:
    F = np.asarray(d.values, float)
    return dataclasses.replace(d, tractive_force=np.minimum(F, share * F.max()))


def test_clipped_channel_is_found_with_its_rows():
    d = _clipped(_sweep())
    (s,) = find_saturation(d)
    F = np.asarray(d.values)
    assert s.side == "largest" and s.level == F.max() and s.channel == d.channel
    assert s.rows == tuple(int(k) + 1 for k in np.nonzero(F == F.max())[0]) and len(s.rows) >= 3
    assert "saturation" in s.describe()


def test_noisy_quantised_and_resting_channels_are_not_saturated():
    d = _sweep()
    assert find_saturation(d) == ()
    # quantised to 50 N: the top readings repeat, but so do the ones next to them
    rng = np.random.default_rng(3)
    F = np.round((20e3 + rng.normal(0, 60, 400)) / 50) * 50
    assert find_saturation(SlipData(np.linspace(0.05, 0.5, 400), F)) == ()
    # a drive log that starts and ends at rest: exactly zero speeds are not a sensor at its range
    log = simulate(VEH, TERRAINS["lete_sand"], kind="drive", seed=1, duration_s=20)
    v = np.asarray(log.vehicle_speed, float).copy()
    v[:30] = 0.0
    assert find_saturation(dataclasses.replace(log, vehicle_speed=v)) == ()


@pytest.mark.slow
def test_diagnosis_of_a_clipped_sweep_names_no_effect_with_confidence():
    d = diagnose(_clipped(_sweep()), VEH)
    assert "clipped_sensor" not in [x.name for x in d.excluded]  # formed: the clipped rows were found
    assert d.verdict == "unexplained" or d.confidence <= 0.5, (d.verdict, d.confidence)
    clean = diagnose(_sweep(), VEH)
    assert "clipped_sensor" in [x.name for x in clean.excluded]


@pytest.mark.slow
def test_an_effect_seen_through_a_clipped_sensor_is_the_effect_or_the_clip():
    # a softening soil (hump_shear) measured by a load cell that clips its four largest readings: the effect
    # is still the best candidate, but the clipped rows bias its fit; the unclipped sweep names it with
    # confidence 1 (measured)
    d0 = simulate(
        VEH,
        TERRAINS["lete_sand"],
        kind="sweep",
        effects={"hump_shear": 0.3},
        seed=1,
        slips=SLIPS,
        noise=SensorNoise(force_rel=0.005, slip_abs=0.0005),
    )
    F = np.asarray(d0.values, float)
    d = dataclasses.replace(d0, tractive_force=np.minimum(F, np.sort(F)[-4]))
    plain, clipped = diagnose(d0, VEH), diagnose(d, VEH)
    assert plain.verdict == "hump_shear" and plain.confidence > 0.5
    # the clipped sensor is weighed beside the effect: the effect or the clip, never a third name
    assert clipped.verdict == "hump_shear" or clipped.cause == "clipped_sensor", (clipped.verdict, clipped.cause)
    assert clipped.verdict != "hump_shear" or clipped.confidence == clipped.weight_of("hump_shear")
