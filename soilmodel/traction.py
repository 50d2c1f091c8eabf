"""Track-terrain interaction: the tractive force of Eq. 2 (full) and Eq. 8 (cohesion-free).

Uniform normal pressure, Janosi-Hanamoto shear, both tracks::

    F = (A c + W tan(phi)) * [1 - K/(i l) * (1 - exp(-i l / K))]

The bracket ``g(x) = 1 - (1 - exp(-x))/x`` with ``x = i l / K`` is evaluated with its Taylor
series for small ``x`` (no division by zero, no cancellation: F(0) = 0 exactly, exact
derivatives at 0). For skid (i < 0) the library uses ``F(i) = -F(|i|)``, a first
approximation (the shear-displacement history of a skidding track differs in reality).

Everything is built once as CasADi ``Function`` objects and called many times; the numpy
helpers broadcast their arguments and evaluate in one call.
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from .errors import DataError
from .soil import Soil
from .vehicle import Vehicle

MODELS = ("full", "cohesion-free")

#: Below this |x| = |i| l / K the bracket is evaluated by its series (truncation < 1e-14 relative).
SERIES_SWITCH = 0.05


def check_model(model: str) -> str:
    """Return ``model`` if it is one of :data:`MODELS`, else raise a clear error."""
    if model not in MODELS:
        raise DataError(f"unknown model {model!r}; expected one of {MODELS}")
    return model


def shear_bracket(x):
    """Odd extension of ``g(x) = 1 - (1 - exp(-x))/x``: ``sign(x) g(|x|)``, series near 0.

    Works on SX, MX and floats. The series branch is written with ``x`` and ``|x|`` so that
    automatic differentiation gives the true slope ``g'(0) = 1/2`` at ``x = 0``.
    """
    a = ca.fabs(x)
    xa = x * a
    series = x * (1 / 2 + x * x * (1 / 24 + x * x * (1 / 720 + x * x / 40320))) \
        - xa * (1 / 6 + x * x * (1 / 120 + x * x / 5040))
    safe = ca.if_else(a < SERIES_SWITCH, 1.0, a)  # keeps the unused branch finite, and its derivative
    exact = ca.sign(x) * (1 + ca.expm1(-safe) / safe)
    return ca.if_else(a < SERIES_SWITCH, series, exact)


def slip_factor(slip, track_length, shear_modulus):
    """The Janosi-Hanamoto slip factor ``g(i l / K)`` of uniform pressure, in (-1, 1); odd in slip."""
    return shear_bracket(slip * track_length / shear_modulus)


def _tan(x):
    return ca.tan(x) if isinstance(x, (ca.SX, ca.MX, ca.DM)) else np.tan(x)


def max_thrust_expr(c, phi, W, area, model: str = "full"):
    """Soil thrust limit ``F_max = A c + W tan(phi)`` (``W tan(phi)`` for cohesion-free).

    The one home of F_max: CasADi expressions, floats or numpy arrays (broadcast).
    """
    check_model(model)
    friction = W * _tan(phi)
    return friction if model == "cohesion-free" else area * c + friction


@lru_cache(maxsize=None)
def max_thrust_function(model: str = "full") -> ca.Function:
    """CasADi Function ``(c, phi, W, A) -> (F_max, dF_max/d[c, phi, W])`` (AD), built once per model."""
    check_model(model)
    c, phi, W, A = (ca.SX.sym(n) for n in ("c", "phi", "W", "A"))
    F = max_thrust_expr(c, phi, W, A, model)
    F = F if isinstance(F, ca.SX) else ca.SX(F)
    return ca.Function(f"max_thrust_{model.replace('-', '_')}", [c, phi, W, A],
                       [F, ca.jacobian(F, ca.vertcat(c, phi, W))], ["c", "phi", "W", "A"], ["F_max", "dF_dcphiW"])


def thrust_expr(slip, c, phi, K, W, track_length, track_width, model: str = "full"):
    """Symbolic tractive force of both tracks (Eq. 2, or Eq. 8 for ``model="cohesion-free"``)."""
    area = 2 * track_width * track_length
    return max_thrust_expr(c, phi, W, area, model) * slip_factor(slip, track_length, K)


@lru_cache(maxsize=None)
def thrust_function(model: str = "full") -> ca.Function:
    """CasADi Function ``F(slip, c, phi, K, W, l, b)`` in SI (built once per model).

    Call it with row vectors of equal length (or scalars) to evaluate many points at once.
    """
    check_model(model)
    s = [ca.SX.sym(n) for n in ("slip", "c", "phi", "K", "W", "l", "b")]
    return ca.Function(f"thrust_{model.replace('-', '_')}", s, [thrust_expr(*s, model=model)],
                       ["slip", "c", "phi", "K", "W", "l", "b"], ["F"])


@lru_cache(maxsize=None)
def slip_factor_function() -> ca.Function:
    """CasADi Function ``g(slip, l, K)``: the slip factor of Eq. 2 (``F = F_max g``), built once.

    Call it with row vectors of equal length (or scalars) to evaluate many points at once.
    """
    s, l, K = ca.SX.sym("slip"), ca.SX.sym("l"), ca.SX.sym("K")
    return ca.Function("slip_factor", [s, l, K], [slip_factor(s, l, K)], ["slip", "l", "K"], ["g"])


@lru_cache(maxsize=None)
def sensitivity_function(model: str = "full") -> ca.Function:
    """CasADi Function ``dF/d[c, phi, K](slip, c, phi, K, W, l, b)`` -> 1x3 row, from AD."""
    check_model(model)
    s = [ca.SX.sym(n) for n in ("slip", "c", "phi", "K", "W", "l", "b")]
    F = thrust_expr(*s, model=model)
    jac = ca.jacobian(F, ca.vertcat(s[1], s[2], s[3]))
    return ca.Function(f"dthrust_{model.replace('-', '_')}", s, [jac],
                       ["slip", "c", "phi", "K", "W", "l", "b"], ["dF_dp"])


def _args(slip, soil: Soil, vehicle: Vehicle, normal_load):
    W = vehicle.weight if normal_load is None else normal_load
    arrays = np.broadcast_arrays(np.asarray(slip, dtype=float), np.asarray(W, dtype=float))
    shape = arrays[0].shape
    row = [a.reshape(1, -1) for a in arrays]
    return shape, [row[0], soil.cohesion, soil.friction_angle, soil.shear_modulus, row[1],
                   vehicle.track_length, vehicle.track_width]


def tractive_force(slip, soil: Soil, vehicle: Vehicle, model: str = "full", normal_load=None) -> np.ndarray:
    """Tractive force of both tracks in newtons, as a numpy array shaped like ``slip``.

    Parameters
    ----------
    slip
        Track slip i (scalar or array). i < 0 is skid, handled as ``F(i) = -F(|i|)``.
    soil, vehicle
        Soil parameters and the vehicle (geometry and normal load W = m g).
    model
        ``"full"`` (Eq. 2) or ``"cohesion-free"`` (Eq. 8, drops ``A c``).
    normal_load
        Normal load W in N (scalar or array broadcastable with ``slip``); defaults to the
        vehicle's weight.
    """
    shape, args = _args(slip, soil, vehicle, normal_load)
    if args[0].size == 0:
        return np.zeros(shape)
    return np.asarray(thrust_function(model)(*args), dtype=float).reshape(shape)


def tractive_force_sensitivities(slip, soil: Soil, vehicle: Vehicle, model: str = "full",
                                 normal_load=None) -> np.ndarray:
    """``dF/dc`` (N/Pa), ``dF/dphi`` (N/rad), ``dF/dK`` (N/m) from CasADi's AD, shape ``(n, 3)``."""
    shape, args = _args(slip, soil, vehicle, normal_load)
    out = np.asarray(sensitivity_function(model)(*args), dtype=float)
    return out.reshape(-1, 3)  # auto-mapped call: 1 x 3n, one [c, phi, K] block per point


def max_thrust(soil: Soil, vehicle: Vehicle, model: str = "full", normal_load=None) -> float | np.ndarray:
    """Soil thrust limit ``F_max = A c + W tan(phi)`` in N (cohesion-free: ``W tan(phi)``)."""
    W = vehicle.weight if normal_load is None else np.asarray(normal_load, dtype=float)
    F = max_thrust_expr(soil.cohesion, soil.friction_angle, W, vehicle.contact_area, model)
    return F if np.ndim(F) else float(F)
