"""The two-point profile check of F_max's standard error (identify/drivelog/profile_check.py): K re-fitted
at F_max -+ 2 SE by projected Levenberg-Marquardt with F_max held must be the minimum over K that a brute-force
scan of the same profiled cost finds, on a log where the quadratic picture holds and on one where it does not."""

import numpy as np
import pytest

from soiltrack.identify.drivelog import fit_drive_log
from soiltrack.identify.drivelog.joint import SLIP_CHUNK, SlipSolver, padded_data
from soiltrack.identify.drivelog.nlp import g_inverse, pad
from soiltrack.identify.drivelog.prepare import SLIP_BOUNDS, prepare_drive_log
from soiltrack.identify.drivelog.profile_check import PROFILE_MIN_RISE, profile_flatness
from soiltrack.identify.drivelog.profiled import nominal_data
from soiltrack.soilmodel import TERRAINS, VEHICLES
from soiltrack.soilmodel.effects import effect_structure
from soiltrack.soilmodel.simulation import simulate_drive_log

LIGHT = VEHICLES["light"]


def _scan_rise(prep, F, Fmax, K, s2, Kb, grid=241):
    """(min over a log-K grid of the profiled cost at F) - cost at (Fmax, K), over s2: brute force."""
    size = -(-prep.n_used // SLIP_CHUNK) * SLIP_CHUNK
    D = np.asfortranarray(padded_data(nominal_data(prep, LIGHT), size))
    solver = SlipSolver(LIGHT, effect_structure(None, LIGHT), D)
    lo, hi = SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3
    s_meas = pad(np.clip(prep.slip_measured, lo, hi), size)

    def cost(f, k):
        y = np.clip(np.abs(prep.thrust) / f, 0.0, 0.98)
        s_inv = pad(np.clip(np.sign(prep.thrust) * g_inverse(y) * k / LIGHT.track_length, lo, hi), size)
        th = np.array([f, k])
        return 2.0 * float(np.sum(solver.costs(th, solver.best(th, [s_inv, s_meas]))))

    ks = np.exp(np.linspace(np.log(Kb[0]), np.log(Kb[1]), grid))
    c = np.array([cost(F, k) for k in ks])
    j = int(np.argmin(c))
    # refine around the best grid point (a finer grid of its two neighbours' span)
    fine = np.exp(np.linspace(np.log(ks[max(j - 1, 0)]), np.log(ks[min(j + 1, grid - 1)]), 41))
    cmin = min(c[j], min(cost(F, k) for k in fine))
    return (cmin - cost(Fmax, K)) / s2


# hard pulls (the 20 s log is slow: 4 s); the first 4 s of a start
@pytest.mark.parametrize("seed, seconds", [pytest.param(3, 20.0, marks=pytest.mark.slow), (5, 4.0)])
def test_profiled_rise_is_the_minimum_over_K(seed, seconds):
    log = simulate_drive_log(LIGHT, TERRAINS["dry_sand"], seed=seed, duration_s=20.0)
    log = log.subset(np.nonzero(log.time <= seconds)[0])
    r = fit_drive_log(log, LIGHT)
    e = r.extra
    Fmax, K, sF, s2 = e["max_thrust_N"], e["shear_modulus_m"], e["max_thrust_stderr_N"], e["reduced_chi2"]
    Kb = tuple(r.to_dict()["bounds"]["shear_modulus_m"])
    prep = prepare_drive_log(log, LIGHT)
    rise = profile_flatness(prep, LIGHT, Fmax, K, sF, s2, Kb)
    assert list(rise) == pytest.approx(e["profile_rise"], rel=1e-9)  # the fit reports this check
    for side, F in zip(rise, (Fmax - 2 * sF, Fmax + 2 * sF)):
        scan = _scan_rise(prep, F, Fmax, K, s2, Kb)
        # the re-fitted K is at least as good as every scanned K, and the scan gets close to it
        assert side <= scan + 1e-6 * max(1.0, abs(scan))
        assert scan - side < 0.05
    assert min(rise) >= PROFILE_MIN_RISE and all(2.0 < x < 8.0 for x in rise)  # about 4: quadratic picture holds
