"""The excitation test of the on-line detector (identify/online/detector.py ``ExcitationTest``): numbers.

Fast tests on synthetic residuals (the statistic's null distribution, its dating of a change inside an
excitation, the model-error inflation), and slow ones on logs of the independent simulator
(``tests/online_oracle.py``) of the tuning set of ``bench_online.py --set tuning`` where the mechanism
made the difference.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from online_oracle import SOILS, random_pulls, simulate
from soiltrack.identify import OnlineEstimator, OnlineSettings
from soiltrack.identify.online.detector import ExcitationTest, score_distance
from soiltrack.soilmodel import VEHICLES


def _grads(n: int, rng) -> np.ndarray:
    """Gradients of a pull's samples: a ramp (along F_max mostly at high load, along K at low load)."""
    load = np.linspace(0.2, 0.95, n)
    return np.column_stack([-3.0 * load, 1.5 * (1 - load) + 0.05 * rng.standard_normal(n)])


def test_score_distance_is_chi_square_two_under_the_held_soil():
    """Residuals drawn around the held estimate (its own error from P, noise N(0, 1)): mean 2, p(>13.8) ~ 1e-3."""
    rng = np.random.default_rng(5)
    P = (0.01, -0.004, 0.02)
    L = np.linalg.cholesky(np.array([[P[0], P[1]], [P[1], P[2]]]))
    vals = []
    for _ in range(4000):
        D = _grads(40, rng)
        delta = L @ rng.standard_normal(2)  # the held estimate's error, shared by the samples
        r = D @ delta + rng.standard_normal(40)
        g = tuple(D.T @ r)
        A = D.T @ D
        vals.append(score_distance(g, (A[0, 0], A[0, 1], A[1, 1]), P))
    vals = np.array(vals)
    assert 1.85 < vals.mean() < 2.15
    assert np.mean(vals > 13.8) < 0.004  # chi-square(2) gives 0.001
    # without P (the held error ignored) the same residuals lean: the statistic is too large
    big = []
    for _ in range(500):
        D = _grads(40, rng)
        r = D @ (L @ rng.standard_normal(2)) + rng.standard_normal(40)
        A = D.T @ D
        big.append(score_distance(tuple(D.T @ r), (A[0, 0], A[0, 1], A[1, 1]), (0.0, 0.0, 0.0)))
    assert np.mean(big) > 2.5


def test_score_distance_singular_information_and_inflation():
    """One operating point (rank-one information): the mean residual's t-statistic squared; inflation divides it."""
    d = np.array([-2.0, 1.0])
    n, mean = 50, 0.5
    A = n * np.outer(d, d)
    g = tuple(n * mean * d)
    val = score_distance(g, (A[0, 0], A[0, 1], A[1, 1]), (0.0, 0.0, 0.0))
    assert val == pytest.approx(n * mean**2, rel=1e-9)
    assert score_distance(g, (A[0, 0], A[0, 1], A[1, 1]), (0.0, 0.0, 0.0), 1 + n * 0.1**2) == pytest.approx(
        n * mean**2 / (1 + n * 0.01), rel=1e-9
    )


def test_excitation_test_dates_a_change_inside_the_excitation():
    """60 samples on the held soil, then 40 leaning: the most likely split and its interval hold sample 60."""
    rng = np.random.default_rng(11)
    X = ExcitationTest(clip=4.0)
    X.begin(0.0, (1.0, 1.0))
    D = _grads(100, rng)
    shift = np.array([0.08, 0.0])  # a weaker soil: the residuals lean along F_max's gradient
    stat = 0.0
    for k in range(100):
        r = rng.standard_normal() + (D[k] @ shift * -10 if k >= 60 else 0.0)
        stat = X.add(0.02 * k, float(r), (float(D[k, 0]), float(D[k, 1])), (1e-4, 0.0, 1e-4))
    assert stat > 27.6
    best, lo, hi = X.change_points(9.0)
    assert lo <= 60 <= hi and abs(best - 60) <= 5 and lo > 0


def test_excitation_settings_checked():
    for name in ("detect_excitation_chi2", "detect_date_margin", "detect_excitation_max_s"):
        with pytest.raises(Exception, match=name):
            OnlineSettings(**{name: 0.0})
    with pytest.raises(Exception, match="detect_excitation_bias"):
        OnlineSettings(detect_excitation_bias=-0.1)
