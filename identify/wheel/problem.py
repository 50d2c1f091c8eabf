"""The rigid wheel's identification problem: parameters, bounds, residuals, the cached IPOPT solver.

Parameters (SI), in the order of every vector here: ``c`` (Pa), ``phi`` (rad), ``K`` (m),
``k_c`` (N/m^(n+1)), ``k_phi`` (N/m^(n+2)), ``n`` (-) and the slip-sinkage coefficient ``s`` (-,
held at 0 unless the ``slip_sinkage`` effect is fitted). IPOPT sees them scaled by
:data:`PARAMETER_SCALES` (kPa, rad, cm, kN/m^(n+1), MN/m^(n+2), 1, 1).

Channels (residuals). Drawbar pull: ``DP_model(i, z) - DP`` per row (z the measured sinkage, or
the one solved from the load). Sinkage, only when it is measured: ``z_W - z`` per row, where
``z_W`` solves the wheel's vertical balance ``W_model(i, z_W) = W`` for the measured load (a
rootfinder); it is what makes the Bekker stiffness identifiable. The balance is compared in
sinkage, not in force, because the sinkage reading is the noisy one (a 0.5 mm error moves the
balance's force by about a newton on a small wheel, far more than a load cell's error): with the
noise on the response side the fit is not biased by errors in its inputs (on simulated sweeps the
force form pulled the Bekker exponent from 1.1 to about 0.4).

Each channel has its own unknown noise level. The objective is the concentrated (profile)
Gaussian log-likelihood ``sum_k n_k / 2 log(SSR_k + n_k s_floor,k^2)`` (SSR_k the channel's sum
of squared residuals), whose minimum is the weighted least-squares fit with each channel's
weight 1 / s_k^2 set to its own residual variance. ``s_floor`` is a resolution floor
(:data:`NOISE_FLOOR_REL` of the mean load for the drawbar pull, :data:`SINKAGE_FLOOR_M` for the
sinkage) that keeps the objective finite on noise-free data.

The NLP is built once per (wheel, settings, number of rows, sinkage measured or not, free
parameters) and cached; the data enter as NLP parameters.
"""

from __future__ import annotations

from typing import Any

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ...soilmodel.rigid_wheel import RigidWheel
from ...soilmodel.soil import PRACTICAL_BOUNDS
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.wheel import WHEEL_PARAMETER_NAMES, WheelSettings, sinkage_from_load_function, wheel_expr

__all__ = [
    "WHEEL_PARAMETERS",
    "PARAMETER_SCALES",
    "WheelBounds",
    "DEFAULT_WHEEL_BOUNDS",
    "NOISE_FLOOR_REL",
    "SINKAGE_FLOOR_M",
    "channel_floors",
    "wheel_solver",
    "N_PARAMETERS",
    "residual_function",
    "bekker_modulus",
    "torque_floor",
    "wheel_block",
    "WHEEL_IPOPT_OPTIONS",
]

#: Parameter names of the wheel fit (SI), in vector order.
WHEEL_PARAMETERS = WHEEL_PARAMETER_NAMES
#: Number of wheel-fit parameters.
N_PARAMETERS = len(WHEEL_PARAMETERS)
#: Scales of the NLP variables (x = theta / scale): kPa, rad, cm, kN/m^(n+1), MN/m^(n+2), 1, 1.
PARAMETER_SCALES = np.array([1e3, 1.0, 1e-2, 1e3, 1e6, 1.0, 1.0])
#: Noise floor of each channel as a fraction of the mean normal load (a rig force sensor resolves about
#: 0.1 % of its range): below it a channel is not weighted further up.
NOISE_FLOOR_REL = 1e-3
#: Noise floor of the sinkage channel, m (a displacement sensor's resolution).
SINKAGE_FLOOR_M = 1e-5

#: IPOPT options of the wheel fit and of the joint fit of several data sets.
WHEEL_IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "print_time": False,
    "ipopt.sb": "yes",
    "ipopt.tol": 1e-10,
    "ipopt.acceptable_tol": 1e-7,
    "ipopt.max_iter": 500,
    # a trial point where the wheel cannot carry a load is NaN: IPOPT's line search then takes a
    # shorter step; the status of the solve says whether it converged
    "show_eval_warnings": False,
}


@dataclass(frozen=True)
class WheelBounds:
    """Box bounds (SI) of the seven wheel-fit parameters, as ``(lower, upper)`` tuples in vector order.

    The soil's are the practical ranges (c 0-69 kPa, phi 6-40 deg, K 0.006-0.05 m); the Bekker
    ranges span the tabulated terrains with room (k_c 0-500 kN/m^(n+1), k_phi 0-20 MN/m^(n+2),
    n 0.1-2); the slip-sinkage coefficient 0-20 (stresses at full slip down to 1/21).
    """

    lower: tuple[float, ...]
    upper: tuple[float, ...]

    def __post_init__(self) -> None:
        if (
            len(self.lower) != N_PARAMETERS
            or len(self.upper) != N_PARAMETERS
            or not all(lo < hi for lo, hi in zip(self.lower, self.upper))
        ):
            raise ValueError(f"wheel bounds need {N_PARAMETERS} (lower < upper) pairs")


DEFAULT_WHEEL_BOUNDS = WheelBounds(
    lower=(
        float(PRACTICAL_BOUNDS.lower[0]),
        float(PRACTICAL_BOUNDS.lower[1]),
        float(PRACTICAL_BOUNDS.lower[2]),
        0.0,
        0.0,
        0.1,
        0.0,
    ),
    upper=(
        float(PRACTICAL_BOUNDS.upper[0]),
        float(PRACTICAL_BOUNDS.upper[1]),
        float(PRACTICAL_BOUNDS.upper[2]),
        500e3,
        20e6,
        2.0,
        20.0,
    ),
)


def bekker_modulus(k_c, k_phi, width):
    """Bekker's k = k_c / b + k_phi of a wheel of width b (the only combination one width sees)."""
    return k_c / width + k_phi


@locked_cache(maxsize=32)
def residual_function(
    wheel: RigidWheel, settings: WheelSettings, measured_sinkage: bool, grouser_input: bool = False
) -> ca.Function:
    """Per-row Function ``(i, z, W, theta[7]) -> (drawbar pull, vertical force, sinkage used, z_W)``.

    ``z_W`` is the sinkage at which the fitted stresses carry the load W. With
    ``measured_sinkage`` the row's z is used for the drawbar pull and the vertical force;
    otherwise z_W is (the input z is ignored). With ``grouser_input`` the grouser height is a last
    input ``h`` (m) instead of the wheel's (the joint fit frees it).
    """
    i, z, W = ca.MX.sym("i"), ca.MX.sym("z"), ca.MX.sym("W")
    th = ca.MX.sym("theta", N_PARAMETERS)
    c, phi, K, k_c, k_phi, n, s = (th[q] for q in range(N_PARAMETERS))
    r, b = wheel.radius, wheel.width
    hs = ca.MX.sym("h")
    h = hs if grouser_input else wheel.grouser_height
    z_fn = sinkage_from_load_function(r, b, wheel.grouser_height, settings, grouser_input=grouser_input)
    z_w = z_fn(i, W, c, phi, K, k_c, k_phi, n, s, *([hs] if grouser_input else []))
    z_used = z if measured_sinkage else z_w
    dp, wl, tq = wheel_expr(i, z_used, c, phi, K, k_c, k_phi, n, r, b, h, settings, slip_sinkage=s)
    extra = [hs] if grouser_input else []
    return ca.Function(
        "wheel_row",
        [i, z, W, th, *extra],
        [dp, wl, z_used, z_w, tq],
        ["i", "z", "W", "theta", *(["h"] if grouser_input else [])],
        ["drawbar_pull", "normal_load", "sinkage", "sinkage_from_load", "torque"],
    )


def channel_floors(mean_load: float) -> tuple[float, float]:
    """Noise floors (drawbar pull N, sinkage m) of the concentrated likelihood."""
    return NOISE_FLOOR_REL * mean_load, SINKAGE_FLOOR_M


def torque_floor(mean_load: float, radius: float) -> float:
    """Noise floor of the torque channel, N m: the drawbar pull's floor times the wheel's radius."""
    return NOISE_FLOOR_REL * mean_load * radius


def wheel_block(
    wheel: RigidWheel,
    settings: WheelSettings,
    n_rows: int,
    measured_sinkage: bool,
    measured_torque: bool,
    theta,
    p,
    grouser_height=None,
) -> tuple[Any, tuple[Any, Any, Any]]:
    """One wheel sweep's concentrated negative log-likelihood and raw residuals (CasADi MX).

    ``theta`` the seven parameters (SI, :data:`WHEEL_PARAMETERS`), ``p`` the sweep's data as
    :func:`wheel_solver` lays them out (``[i, z, W, DP(, T, weights)]``, n each; anything after is
    ignored); ``grouser_height`` (MX, optional) in place of the wheel's. Returns ``(f, (r_dp, r_z, r_t))``;
    ``r_z``, ``r_t`` zeros where not measured. The
    one home of the wheel's objective: the wheel's own fit and the joint fit of several data sets
    (:mod:`soiltrack.identify.datasets`) both build it here.
    """
    i, z, W, DP = (p[q * n_rows : (q + 1) * n_rows] for q in range(4))
    h_in = grouser_height is not None
    row = residual_function(wheel, settings, measured_sinkage, h_in).map(n_rows)
    extra = [ca.repmat(grouser_height, 1, n_rows)] if h_in else []
    dp, _, _, z_w, tq = row(i.T, z.T, W.T, ca.repmat(theta, 1, n_rows), *extra)
    r_dp = dp.T - DP
    r_w = (z_w.T - z) if measured_sinkage else ca.MX.zeros(n_rows, 1)
    f = n_rows / 2 * ca.log(ca.sumsqr(r_dp) + n_rows * (NOISE_FLOOR_REL * ca.sum1(W) / n_rows) ** 2)
    if measured_sinkage:
        f = f + n_rows / 2 * ca.log(ca.sumsqr(r_w) + n_rows * SINKAGE_FLOOR_M**2)
    r_t = ca.MX.zeros(n_rows, 1)
    if measured_torque:
        T, wt = p[4 * n_rows : 5 * n_rows], p[5 * n_rows : 6 * n_rows]
        r_t = (tq.T - T) * wt
        floor_t = NOISE_FLOOR_REL * ca.sum1(W) / n_rows * wheel.radius
        f = f + n_rows / 2 * ca.log(ca.sumsqr(r_t) + n_rows * floor_t**2)
    return f, (r_dp, r_w, r_t)


@locked_cache(maxsize=64)
def wheel_solver(
    wheel: RigidWheel,
    settings: WheelSettings,
    n_rows: int,
    measured_sinkage: bool,
    free: tuple[bool, ...],
    measured_torque: bool = False,
) -> tuple[ca.Function, ca.Function]:
    """The cached IPOPT solver and its residual/Jacobian Function.

    NLP variables: the free parameters scaled (``theta / PARAMETER_SCALES``); NLP parameters
    ``p = [i (n), z (n), W (n), DP (n), fixed theta (7)]``. Returns ``(solver, resid)`` with
    ``resid(x_free, p) -> (r_dp, r_z, J_dp, J_z, theta)``: raw residuals (drawbar pull N, sinkage
    m) and their Jacobians with respect to the SI free parameters. With ``measured_torque`` the
    torque is a third channel: ``p`` carries after DP the torque T (n) and its row weights (n,
    1 / relative standard deviation), and ``resid`` returns after theta the weighted torque
    residual (N m) and its Jacobian.
    """
    nf = sum(free)
    x = ca.MX.sym("x", nf)
    nch = 6 if measured_torque else 4
    p = ca.MX.sym("p", nch * n_rows + N_PARAMETERS)
    fixed = p[nch * n_rows :]
    parts, q = [], 0
    for k in range(N_PARAMETERS):
        if free[k]:
            parts.append(x[q] * PARAMETER_SCALES[k])
            q += 1
        else:
            parts.append(fixed[k])
    theta = ca.vertcat(*parts)
    f, (r_dp, r_w, r_t) = wheel_block(wheel, settings, n_rows, measured_sinkage, measured_torque, theta, p)
    opts = dict(WHEEL_IPOPT_OPTIONS)
    nlp: dict[str, Any] = {"x": x, "p": p, "f": f}
    solver = ca.nlpsol("wheel_fit", "ipopt", nlp, opts)
    xs = ca.MX.sym("xs", nf)
    th_si = ca.substitute(theta, x, xs)
    r_dp_s, r_w_s, r_t_s = ca.substitute([r_dp, r_w, r_t], [x], [xs])
    scale = ca.DM(PARAMETER_SCALES[np.array(free)])
    J_dp = ca.jacobian(r_dp_s, xs) / ca.repmat(scale.T, n_rows, 1)
    J_w = ca.jacobian(r_w_s, xs) / ca.repmat(scale.T, n_rows, 1)
    J_t = ca.jacobian(r_t_s, xs) / ca.repmat(scale.T, n_rows, 1)
    resid = ca.Function("wheel_resid", [xs, p], [r_dp_s, r_w_s, J_dp, J_w, th_si, r_t_s, J_t])
    return solver, resid
