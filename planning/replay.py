"""Open-loop replay of a planned torque profile through the full (stiff) dynamics of the model core.

The planned torque is held over each interval (zero-order hold) and the dynamics of
:func:`soiltrack.soilmodel.dynamics.dynamics_expr` (Eqs. 1, 4 and the thrust-balance sprocket
equation, grade as the ``grade`` effect) plus the Bekker compaction resistance of the patch
are integrated by CVODES (implicit BDF), with ``substeps`` output points inside every
interval, so that limits can be checked between the mesh points. The start is the planned
initial speed with the sprocket at the planned initial slip.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..soilmodel import DataError, Vehicle
from ..soilmodel.dynamics import dynamics_expr
from ..soilmodel.threadsafe import call_solver, locked_cache

__all__ = ["Replay", "replay", "step_function"]


@dataclass(frozen=True)
class Replay:
    """Replayed trajectory: arrays over all output points (``substeps`` per interval, plus the start).

    ``node`` marks the points that coincide with the plan's mesh points.
    """

    time: np.ndarray
    speed: np.ndarray
    sprocket_speed: np.ndarray
    slip: np.ndarray
    torque: np.ndarray
    power: np.ndarray
    node: np.ndarray


@locked_cache(maxsize=16)
def step_function(vehicle: Vehicle, substeps: int) -> ca.Function:
    """CVODES over one held-torque interval: ``x0 = [v, w]``, ``p = [M, c, phi, K, theta, R_c, dt, mu_s]``, with
    ``substeps`` equally spaced outputs (``mu_s``: the ``slip_sinkage`` coefficient, 0 for the nominal model)."""
    x = ca.SX.sym("x", 2)
    p = ca.SX.sym("p", 8)  # M, c, phi, K, theta, R_c, dt, mu_s
    eff = {"grade": {"theta_rad": p[4]}, "slip_sinkage": {"mu_s": p[7]}}
    d = dynamics_expr(x[0], x[1], p[0], p[1], p[2], p[3], vehicle, eff)
    dv = d["dv"] - p[5] / vehicle.mass
    ode = p[6] * ca.vertcat(dv, d["dw"])  # normalised time tau in [0, 1]
    grid = list(np.linspace(0.0, 1.0, substeps + 1)[1:])
    F = ca.integrator(
        "replay",
        "cvodes",
        {"x": x, "p": p, "ode": ode},
        0.0,
        grid,
        {"abstol": 1e-10, "reltol": 1e-9, "max_num_steps": 100000, "show_eval_warnings": False},
    )
    return F


def replay(result, vehicle: Vehicle, substeps: int = 8) -> Replay:
    """Replay a successful :class:`~.profile.SpeedPlan` open-loop (ZOH torque) with CVODES."""
    if not result.success or not result.mesh:
        raise DataError("only a successful profile can be replayed")
    m = result.mesh
    r = vehicle.sprocket_radius
    n = len(m["torque"])
    step = step_function(vehicle, substeps)
    v0 = float(m["v"][0])
    x = np.array([v0, float(m["w"][0])])
    T, V, Wv, Mq = [0.0], [x[0]], [x[1]], [float(m["torque"][0])]
    node = [True]
    t = 0.0
    for k in range(n):
        p = [
            float(m["torque"][k]),
            float(m["c"][k]),
            float(m["phi"][k]),
            float(m["K"][k]),
            float(m["grade_rad"][k]),
            float(m["compaction_N"][k]),
            float(m["dt"][k]),
            float(m["mu_s"][k]) if "mu_s" in m else 0.0,
        ]
        out, _ = call_solver(step, x0=x, p=p)
        X = np.asarray(out["xf"], dtype=float)
        for j in range(substeps):
            T.append(t + m["dt"][k] * (j + 1) / substeps)
            V.append(X[0, j])
            Wv.append(X[1, j])
            Mq.append(p[0])
            node.append(j == substeps - 1)
        t += float(m["dt"][k])
        x = X[:, -1]
    t_a, v_a, w_a, m_a = (np.asarray(a) for a in (T, V, Wv, Mq))
    slip = 1 - v_a / (r * w_a)
    return Replay(t_a, v_a, w_a, slip, m_a, m_a * w_a, np.asarray(node))
