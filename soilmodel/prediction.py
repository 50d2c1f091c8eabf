"""Forward prediction for design: pull, thrust, torque and sinkage of a running gear against slip.

Composed of the library's one home of each piece of physics, as one CasADi Function per gear
(built once, cached; mapped over the slips) with the exact gradient of every output with respect
to the soil's parameters (:data:`PREDICTION_PARAMETERS`, SI) for propagating their uncertainty:

rigid wheel (:mod:`.wheel`, Wong-Reece)
    the sinkage z at which the stresses carry the load W (:func:`~.wheel.sinkage_from_load_function`),
    then at that z the drawbar pull DP, the driving torque T and the thrust: the horizontal part
    of the shear stress alone, i.e. DP minus DP of the same wheel at the same sinkage with no
    shear (c = 0, phi = 0: the normal stresses' compaction resistance), so DP = thrust - R_c.
tracked vehicle (:mod:`.traction`, :mod:`.sinkage`)
    thrust F(i) of Eq. 2 at the load W, drawbar pull ``F - mu_r W - R_c`` (the vehicle's rolling
    resistance and, with Bekker parameters, Bekker's compaction resistance R_c at the static
    sinkage z0), sprocket torque of both tracks at steady speed ``r F`` (the thrust balance),
    sinkage z0 (static: no slip sinkage).
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from .sinkage import compaction_expr, sinkage_expr
from .traction import thrust_expr
from .wheel import (
    DEFAULT_WHEEL_SETTINGS,
    WHEEL_PARAMETER_NAMES,
    WheelSettings,
    sinkage_from_load_function,
    wheel_forces_function,
)

__all__ = [
    "PREDICTION_PARAMETERS",
    "PREDICTION_OUTPUTS",
    "wheel_prediction_function",
    "track_prediction_function",
    "evaluate_prediction",
]

#: The soil's parameters a prediction depends on (SI): c (Pa), phi (rad), K (m), k_c (N/m^(n+1)),
#: k_phi (N/m^(n+2)), n, and the wheel's slip-sinkage coefficient s (0: none).
PREDICTION_PARAMETERS = WHEEL_PARAMETER_NAMES
#: The outputs, in order: drawbar pull (N), thrust (N), torque (N m), sinkage (m).
PREDICTION_OUTPUTS = ("drawbar_pull", "thrust", "torque", "sinkage")


@lru_cache(maxsize=16)
def wheel_prediction_function(
    r: float, b: float, h: float = 0.0, settings: WheelSettings = DEFAULT_WHEEL_SETTINGS
) -> ca.Function:
    """``(i, W, q) -> (y, dy/dq, W_carried)`` of a rigid wheel; ``y = [DP, thrust, T, z]``, ``q`` 7 SI parameters.

    ``W_carried`` is the load the stresses carry at the solved sinkage: it differs from W where
    the wheel cannot carry W (it would sink past its axle) and the outputs are then no answer.
    """
    i, W = ca.MX.sym("i"), ca.MX.sym("W")
    q = ca.MX.sym("q", len(PREDICTION_PARAMETERS))
    args = [q[k] for k in range(q.shape[0])]
    z = sinkage_from_load_function(r, b, h, settings)(i, W, *args)
    forces = wheel_forces_function(r, b, h, settings)
    dp, wl, tq = forces(i, z, *args)
    dp0, _, _ = forces(i, z, 0.0, 0.0, *args[2:])  # no shear: -(compaction resistance) at this sinkage
    y = ca.vertcat(dp, dp - dp0, tq, z)
    return ca.Function(
        "wheel_prediction", [i, W, q], [y, ca.jacobian(y, q), wl], ["i", "W", "q"], ["y", "dy_dq", "W_carried"]
    )


@lru_cache(maxsize=4)
def track_prediction_function(model: str = "full", bekker: bool = True) -> ca.Function:
    """``(i, W, q, l, b, r, mu_r) -> (y, dy/dq, W)`` of a tracked vehicle; ``y = [DP, F, M_s, z0]``.

    Without ``bekker`` the compaction resistance and the sinkage are 0 (the soil has no Bekker
    parameters; the caller reports the sinkage as unknown).
    """
    i, W, l, b, r, mu = (ca.SX.sym(n) for n in ("i", "W", "l", "b", "r", "mu_r"))
    q = ca.SX.sym("q", len(PREDICTION_PARAMETERS))
    F = thrust_expr(i, q[0], q[1], q[2], W, l, b, model=model)
    if bekker:
        R = compaction_expr(W, q[5], q[3], q[4], l, b)
        z = sinkage_expr(W, q[5], q[3], q[4], l, b)
    else:
        R, z = ca.SX(0), ca.SX(0)
    y = ca.vertcat(F - mu * W - R, F, r * F, z)
    return ca.Function(
        "track_prediction",
        [i, W, q, l, b, r, mu],
        [y, ca.jacobian(y, q), W],
        ["i", "W", "q", "l", "b", "r", "mu_r"],
        ["y", "dy_dq", "W_carried"],
    )


def evaluate_prediction(fn: ca.Function, slips: np.ndarray, load: float, q: np.ndarray, *extra: float):
    """``fn`` over ``slips``: outputs (n x 4), gradients (n x 4 x 7) and the carried load (n,)."""
    slips = np.asarray(slips, dtype=float).ravel()
    m = fn.map(int(slips.size))
    y_dm, G_dm, wl = m(ca.DM(slips.reshape(1, -1)), float(load), ca.DM(np.asarray(q, dtype=float)), *extra)
    y = np.asarray(y_dm, dtype=float).T  # (n, 4)
    nq = len(PREDICTION_PARAMETERS)
    G = np.asarray(G_dm, dtype=float).reshape(len(PREDICTION_OUTPUTS), nq, slips.size, order="F").transpose(2, 0, 1)
    return y, G, np.asarray(wl, dtype=float).ravel()
