"""Held-out residuals of drive-log fits per channel (``FitResult.residuals_on`` for drive logs)."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from soiltrack.identify.drivelog.fit import drive_log_residuals, fit_drive_log
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, max_thrust
from soiltrack.soilmodel.simulation import simulate_drive_log

LIGHT, DRY_SAND = VEHICLES["light"], TERRAINS["dry_sand"]
GRADE = math.radians(3.0)
CHANNELS = {"sprocket_speed_rad_s", "thrust_N", "hull_N"}


@pytest.fixture(scope="module")
def fits():
    log = simulate_drive_log(LIGHT, DRY_SAND, seed=0, effects={"grade": GRADE}, duration_s=30)
    return fit_drive_log(log, LIGHT, effects=["grade"]), fit_drive_log(log, LIGHT)


@pytest.fixture(scope="module")
def block():
    return simulate_drive_log(LIGHT, DRY_SAND, seed=5, effects={"grade": GRADE}, duration_s=20, noise="none")


@pytest.mark.slow
def test_residuals_on_noise_free_block(fits, block):
    """Held-out noise-free block: the true model's residuals are at the discretisation level
    (far below the noise); the fitted model's are zero-mean against the noise; the nominal
    model leaves the grade's force W sin(theta) in the hull channel."""
    res, nominal_fit = fits
    truth = {
        "max_thrust_N": max_thrust(DRY_SAND, LIGHT, normal_load=LIGHT.weight * math.cos(GRADE)),
        "shear_modulus_m": DRY_SAND.shear_modulus,
        "effects": {"grade.theta_rad": GRADE},
        "structure": ["grade"],
        "hull_in_fit": True,
        "noise": {
            k: (v["abs"], v["rel"])
            for k, v in zip(("torque", "sprocket_speed", "vehicle_speed"), res.extra["noise_model"].values())
        },
    }
    out = drive_log_residuals(truth, block, LIGHT)
    for ch, r in out["channels"].items():  # whitened means measured: 0.0005, 0.013, 0.002
        assert abs(np.mean(r / out["sigma"][ch])) < 0.05, (ch, np.mean(r / out["sigma"][ch]))
    fitted = drive_log_residuals(res, block, LIGHT)
    hook = res.residuals_on(block)
    for ch, r in fitted["channels"].items():
        np.testing.assert_array_equal(hook[ch], r)
        assert abs(np.mean(r / fitted["sigma"][ch])) < 0.2, (ch, np.mean(r / fitted["sigma"][ch]))
    nominal = nominal_fit.residuals_on(block)
    W_sin = LIGHT.weight * math.sin(GRADE)
    assert np.nanmean(nominal["hull_N"]) == pytest.approx(-W_sin, rel=0.1)  # measured -15.8 N vs -15.7 N


@pytest.mark.slow
def test_residual_hook_pickles_and_refuses_a_failed_fit(fits, block):
    res, _ = fits
    again = pickle.loads(pickle.dumps(res.residual_model))
    assert set(again.residuals_on(res, block)) == CHANNELS
    failed = fit_drive_log(block, LIGHT, max_iter=1, multistart=False)
    assert not failed.success
    with pytest.raises(DataError, match="did not succeed"):
        failed.residuals_on(block)


@pytest.mark.slow
def test_effect_fits_and_residuals_from_threads_match_serial(fits, block):
    """Two effect fits and their held-out residuals from a ThreadPoolExecutor equal the serial ones
    (cached solvers go through the one solver lock; measured with 4 threads and 4 logs too)."""
    from concurrent.futures import ThreadPoolExecutor

    logs = [simulate_drive_log(LIGHT, DRY_SAND, seed=k, effects={"grade": GRADE}, duration_s=12) for k in (1, 2)]
    serial = [fit_drive_log(lg, LIGHT, effects=["grade"]) for lg in logs]
    with ThreadPoolExecutor(2) as ex:
        par = list(ex.map(lambda lg: fit_drive_log(lg, LIGHT, effects=["grade"]), logs))
        res = list(ex.map(lambda r: r.residuals_on(block), par))
    for a, b, r in zip(serial, par, res):
        assert a.success and np.array_equal(a.theta, b.theta)
        assert a.effects["grade"]["theta_rad"].value == b.effects["grade"]["theta_rad"].value
        for ch, x in a.residuals_on(block).items():
            np.testing.assert_array_equal(x, r[ch])
