"""The share of each channel's noise a drive log's latent slip leaves (the diagnosis weighs the channels by it)."""

from __future__ import annotations

import numpy as np
import pytest

from soiltrack.identify import fit
from soiltrack.identify.drivelog.joint import sample_outputs
from soiltrack.identify.drivelog.residuals import drive_log_residuals, evaluate_residuals
from soiltrack.identify.drivelog.sensitivity import latent_slip_expectation
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate


@pytest.fixture(scope="module")
def light_fit():
    v = VEHICLES["light"]
    log = simulate(v, TERRAINS["lete_sand"], kind="drive", seed=2, duration_s=60)
    return v, log, fit(log, v, hull_channel=True)


def test_the_channels_slip_derivative_agrees_with_finite_differences(light_fit):
    v, log, res = light_fit
    _, ctx = evaluate_residuals(res, log, v, None)
    th, st, D = ctx["theta"], ctx["structure"], ctx["D"]
    slip = np.clip(drive_log_residuals(res, log, v)["slip"], -0.5, 0.5)
    ad = sample_outputs(v, st, "sensitivity", th, slip, D)[3]
    h = 1e-6
    up = sample_outputs(v, st, "residual", th, slip + h, D)[1]
    down = sample_outputs(v, st, "residual", th, slip - h, D)[1]
    fd = (up - down) / (2 * h)
    scale = np.maximum(np.abs(fd), 1.0)
    assert np.max(np.abs(ad - fd) / scale) < 1e-4


def test_what_the_latent_slip_leaves_is_what_an_effect_free_log_shows(light_fit):
    v, log, res = light_fit
    ex = latent_slip_expectation(res, log, v)
    out = drive_log_residuals(res, log, v)
    keep = np.asarray(out["keep"])
    used = np.nonzero(keep)[0] if keep.dtype == bool else keep.astype(int)
    shares = {}
    for ch, e in ex.items():
        assert e.shape == (log.n_samples,)
        assert np.all(np.isnan(np.delete(e, used)))
        assert np.all((e[used] >= 0) & (e[used] <= 1))
        z = out["channels"][ch] / out["sigma"][ch]
        ok = np.isfinite(z)
        shares[ch] = (float(np.mean(e[used][ok])), float(np.mean(z[ok] ** 2)))
    # the slip is fitted to each sample's own readings: it takes up most of the hull balance's noise and
    # little of the encoder's; in the fit's own standardisation the effect-free residuals keep what it leaves
    assert shares["hull_N"][0] < 0.4 < 0.9 < shares["sprocket_speed_rad_s"][0]
    # measured (expected / seen): speed 0.997 / 1.011, thrust 0.813 / 0.785, hull 0.191 / 0.187; the old
    # floors from the residuals' second differences put the hull at 0.58 of the fit's noise level instead
    for ch, (expected, seen) in shares.items():
        assert seen == pytest.approx(expected, abs=0.05), (ch, expected, seen)
    # the sample keeps (channels - 1) degrees of freedom, to within the thrust's decorrelation from the speed
    assert sum(e for e, _ in shares.values()) == pytest.approx(2.0, abs=0.1)
