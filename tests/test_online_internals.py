"""The on-line estimator's speed-ups against their plain versions (white-box: same numbers).

- the horizon's use mask and its peak thrust are kept incrementally (a time-ordered deque and a
  running maximum) instead of recomputed over the ring buffer at every update;
- a converged iteration takes the tracking step (one guarded slip step) instead of the full one;
- the thrust residual's derivatives go through the slip factor's local second-order model.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from conftest import bench_module
from soiltrack.identify import OnlineEstimator, OnlineSettings
from soiltrack.identify.online import kernels as K
from soiltrack.soilmodel import VEHICLES

LIGHT = VEHICLES["light"]
M = K.ROWS.index("m")


@pytest.fixture(scope="module")
def two_track_rows():
    b = bench_module("bench_online")
    log, _ = b.change_log(50.0, seed=3, duration_s=45.0)
    cols = b.two_track(log, [(8.0, 9.5), (20.0, 21.0), (36.0, 37.5)], seed=3)
    keys = (
        "time_s",
        "sprocket_torque_left_Nm",
        "sprocket_torque_right_Nm",
        "sprocket_speed_left_rad_s",
        "sprocket_speed_right_rad_s",
        "vehicle_speed_m_s",
    )
    rows = [list(r) for r in zip(*(cols[k].tolist() for k in keys))]
    for k in (300, 301, 1500):  # dropouts
        rows[k][3] = float("nan")
    return rows, cols["yaw_rate_rad_s"].tolist()


def test_incremental_horizon_is_the_recomputed_one(two_track_rows):
    rows, yaw = two_track_rows
    est = OnlineEstimator(LIGHT, OnlineSettings(window_s=5.0))
    checked = 0
    for row, y in zip(rows, yaw):
        e = est.update_tracks(*row, yaw_rate=y)
        t = e.time_s
        if not np.any(est._tslot == t):  # the sample did not enter the horizon: no iteration ran
            continue
        cutoff = max(t - est.settings.window_s, est._t_reset)
        seen = est._ok * (est._tslot >= cutoff)
        m = seen.copy()
        m[est.held_back()] = 0.0  # waiting for the next sample or the slip trend (the relaxation rule)
        np.testing.assert_array_equal(est._D[:, M], m)
        # the running maximum covers the horizon's samples, the held-back ones included
        peak = float(np.max(est._peak, where=seen > 0, initial=0.0))
        got = max(est._peaks[0][2], 0.0) if est._peaks else 0.0
        assert got == peak
        checked += 1
    assert checked > 0.9 * len(rows)
    # LIGHT has no tread_m: the turning samples are counted as not fitted by the steering model
    assert est.samples_turning == 0 and est.turning.not_fitted["no_tread"] > 100 and est.samples_skipped == 3
    assert len(est.changes) == 1 and est._cap >= 256  # the change forgot samples; the buffer grew


def test_tracking_step_is_the_full_step_once_converged(two_track_rows):
    rows, yaw = two_track_rows
    est = OnlineEstimator(LIGHT, OnlineSettings(window_s=5.0))
    compared = 0
    for k, (row, y) in enumerate(zip(rows, yaw)):
        e = est.update_tracks(*row, yaw_rate=y)
        if k % 97 or not e.converged or est._covariance() is None:
            continue
        keep = est._Z.copy()
        V = est._covariance()
        est._c_step()
        full = (est._x_out.copy(), est._sums.copy())
        est._c_track()
        track = (est._x_out.copy(), est._sums.copy())
        np.copyto(est._Z, keep)
        # the steps agree to a hundredth of a standard error
        sF, sK = np.sqrt(V[0]) / est._F_ref, np.sqrt(V[2]) / est._K_ref
        assert abs(track[0][0] - full[0][0]) <= 0.01 * sF
        assert abs(track[0][1] - full[0][1]) <= 0.01 * sK
        # ... and so do the sums the covariance and the Newton step come from
        for name in ("cost", "A11", "A12", "A22", "B11", "B12", "B22", "n_used"):
            j = K.SUMS.index(name)
            assert track[1][j] == pytest.approx(full[1][j], rel=1e-3)
        compared += 1
    assert compared >= 10


def test_local_model_derivatives_are_the_direct_ones():
    row = ca.SX.sym("row", len(K.ROWS))
    p = ca.SX.sym("p", len(K.PARAMS))
    P = {name: p[j] for j, name in enumerate(K.PARAMS)}
    xs, i = ca.SX.sym("xs", 2), ca.SX.sym("i")
    z = ca.vertcat(xs, i)
    _, e = K._residuals(row, i, xs[0], xs[1], P["F_ref"], P["K_ref"], P["l"])
    direct = ca.Function("d", [row, p, xs, i], [e, ca.gradient(e, z), ca.hessian(e, z)[0]])
    local = ca.Function("l", [row, p, xs, i], list(K._thrust_residual_derivatives(row, i, xs, P, z)))
    rng = np.random.default_rng(0)
    pv = np.zeros(len(K.PARAMS))
    pv[[K.PARAMS.index(n) for n in ("F_ref", "K_ref", "l")]] = (300.0, 0.03, 1.2)
    for _ in range(50):
        rv = [1 + rng.random(), 1.2 + rng.random(), 300 * rng.random(), rng.random(), 30 * rng.random(), 0.01, 1.0]
        xv = 0.3 + rng.random(2)
        iv = rng.uniform(-0.2, 0.9) * (0.001 if rng.random() < 0.2 else 1.0)  # also the bracket's series branch
        for a, b in zip(local(rv, pv, xv, iv), direct(rv, pv, xv, iv)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=1e-9)


def test_estimate_fast_constructor_is_the_dataclass_one():
    from soiltrack.identify import OnlineEstimate

    est = OnlineEstimator(LIGHT)
    e = est.update(0.0, 1.0, 10.0, 0.7)
    fields = {k: getattr(e, k) for k in OnlineEstimate.__dataclass_fields__}
    assert OnlineEstimate(**fields).as_dict() == e.as_dict()
    with pytest.raises(TypeError):
        OnlineEstimate.from_fields({k: v for k, v in fields.items() if k != "slip"})
    with pytest.raises(TypeError):
        OnlineEstimate.from_fields({**fields, "extra": 1})
    with pytest.raises(AttributeError):
        e.slip = 0.1
