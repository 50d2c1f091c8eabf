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
    series = x * (1 / 2 + x * x * (1 / 24 + x * x * (1 / 720 + x * x / 40320))) - xa * (
        1 / 6 + x * x * (1 / 120 + x * x / 5040)
    )
    safe = ca.if_else(a < SERIES_SWITCH, 1.0, a)  # keeps the unused branch finite, and its derivative
    exact = ca.sign(x) * (1 + ca.expm1(-safe) / safe)
    return ca.if_else(a < SERIES_SWITCH, series, exact)


@lru_cache(maxsize=1)
def _bracket_table() -> tuple[np.ndarray, np.ndarray]:
    """``(g(x), x)`` of :func:`shear_bracket` at x = 0 and 8,001 log-spaced points in [1e-8, 1e4]."""
    x = np.concatenate([[0.0], np.logspace(-8.0, 4.0, 8001)])
    xs = ca.SX.sym("x")
    g = ca.Function("shear_bracket", [xs], [shear_bracket(xs)]).map(x.size)
    return np.asarray(g(x.reshape(1, -1)), dtype=float).ravel(), x


def shear_bracket_inverse(y) -> np.ndarray:
    """``x >= 0`` with ``g(x) = y`` (:func:`shear_bracket`) for ``y`` in [0, 1), numpy, vectorised.

    Interpolated in a table of the one :func:`shear_bracket` (monotone; built once, 8,001
    log-spaced points up to x = 1e4), exact to about 1e-5 relative; ``y`` is clipped to
    [0, 0.999]. Meant for start points: a start slip from a thrust is ``i = x K / l`` with
    ``x = shear_bracket_inverse(F / F_max)``.
    """
    y = np.clip(np.asarray(y, dtype=float), 0.0, 0.999)
    g, x = _bracket_table()
    return np.interp(y, g, x)


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
    return ca.Function(
        f"max_thrust_{model.replace('-', '_')}",
        [c, phi, W, A],
        [F, ca.jacobian(F, ca.vertcat(c, phi, W))],
        ["c", "phi", "W", "A"],
        ["F_max", "dF_dcphiW"],
    )


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
    F = thrust_expr(s[0], s[1], s[2], s[3], s[4], s[5], s[6], model=model)
    return ca.Function(f"thrust_{model.replace('-', '_')}", s, [F], ["slip", "c", "phi", "K", "W", "l", "b"], ["F"])


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
    F = thrust_expr(s[0], s[1], s[2], s[3], s[4], s[5], s[6], model=model)
    jac = ca.jacobian(F, ca.vertcat(s[1], s[2], s[3]))
    return ca.Function(
        f"dthrust_{model.replace('-', '_')}", s, [jac], ["slip", "c", "phi", "K", "W", "l", "b"], ["dF_dp"]
    )


def resolve_soil(soil, vehicle: Vehicle, model: str | None = None, normal_load=None) -> tuple[Soil, str]:
    """The :class:`Soil` and model to predict with, from a ``Soil`` or a fit result.

    A fit result (``soiltrack.identify.FitResult``, or any object with a method
    ``prediction_soil(normal_load) -> Soil`` and a ``model`` attribute) is asked for a soil that
    reproduces its fitted curve at the requested normal load(s). At one normal load c and phi
    are not separable, but every point of the c-phi ridge gives the same curve at THAT load, so
    the prediction is well determined there and refused (DataError) at any other load.

    Raises
    ------
    DataError
        ``soil`` is ``None`` (e.g. ``FitResult.soil`` when c and phi were not separable) or not
        a soil, or the fit result cannot predict at the requested load.
    """
    if isinstance(soil, Soil):
        return soil, check_model(model or "full")
    hook = getattr(soil, "prediction_soil", None)
    if callable(hook):
        W = vehicle.weight if normal_load is None else normal_load
        fitted_model = getattr(soil, "model", None) or "full"
        if model is not None and check_model(model) != fitted_model:
            raise DataError(
                f"the fit used the {fitted_model} model; predicting with model={model!r} would mix "
                "models (leave model out to use the fitted one)"
            )
        return hook(W), check_model(fitted_model)
    if soil is None:
        raise DataError(
            "no soil given (None). FitResult.soil is None when c and phi are not separable (one "
            "normal load) or the fit failed: pass the FitResult itself, which predicts at the "
            "fitted normal load(s), e.g. tractive_force(slip, result, vehicle)"
        )
    raise DataError(f"soil must be a Soil or a fit result, got {type(soil).__name__}")


@lru_cache(maxsize=256)
def _mapped(kind: str, model: str, n: int) -> ca.Function:
    """``thrust_function(model)`` (``kind="F"``) or ``sensitivity_function(model)`` mapped over n points.

    Cached per size: calling a scalar Function with rows of n points makes CasADi build a new
    map on every call, which costs more than the evaluation itself.
    """
    f = thrust_function(model) if kind == "F" else sensitivity_function(model)
    return f.map(n)


def _args(slip, soil: Soil, vehicle: Vehicle, normal_load):
    W = vehicle.weight if normal_load is None else normal_load
    arrays = np.broadcast_arrays(np.asarray(slip, dtype=float), np.asarray(W, dtype=float))
    shape = arrays[0].shape
    row = [a.reshape(1, -1) for a in arrays]
    return shape, [
        row[0],
        soil.cohesion,
        soil.friction_angle,
        soil.shear_modulus,
        row[1],
        vehicle.track_length,
        vehicle.track_width,
    ]


def tractive_force(slip, soil, vehicle: Vehicle, model: str | None = None, normal_load=None) -> np.ndarray:
    """Tractive force of both tracks in newtons, as a numpy array shaped like ``slip``.

    Parameters
    ----------
    slip
        Track slip i (scalar or array). i < 0 is skid, handled as ``F(i) = -F(|i|)``.
    soil
        A :class:`Soil`, or a fit result (``FitResult``): then the fitted curve, valid at the
        fitted normal load(s) when c and phi were not separable (refused elsewhere; see
        :func:`resolve_soil`).
    vehicle
        The vehicle (geometry and normal load W = m g).
    model
        ``"full"`` (Eq. 2) or ``"cohesion-free"`` (Eq. 8, drops ``A c``); default ``"full"``
        for a Soil, the fitted model for a fit result.
    normal_load
        Normal load W in N (scalar or array broadcastable with ``slip``); defaults to the
        vehicle's weight.
    """
    soil, model = resolve_soil(soil, vehicle, model, normal_load)
    shape, args = _args(slip, soil, vehicle, normal_load)
    if args[0].size == 0:
        return np.zeros(shape)
    return np.asarray(_mapped("F", model, args[0].size)(*args), dtype=float).reshape(shape)


def thrust_at(
    slip, cohesion, friction_angle, shear_modulus, normal_load, vehicle: Vehicle, model: str = "full"
) -> np.ndarray:
    """Eq. 2 / Eq. 8 at many points, each with its own soil and load (SI arrays, broadcast together).

    One mapped CasADi call for all points (e.g. several soils' curves at once).
    """
    arrays = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (slip, cohesion, friction_angle, shear_modulus, normal_load))
    )
    shape = arrays[0].shape
    if arrays[0].size == 0:
        return np.zeros(shape)
    rows = [a.reshape(1, -1) for a in arrays]
    out = _mapped("F", check_model(model), rows[0].shape[1])(
        *rows[:4], rows[4], vehicle.track_length, vehicle.track_width
    )
    return np.asarray(out, dtype=float).reshape(shape)


def tractive_force_sensitivities(
    slip, soil: Soil, vehicle: Vehicle, model: str = "full", normal_load=None
) -> np.ndarray:
    """``dF/dc`` (N/Pa), ``dF/dphi`` (N/rad), ``dF/dK`` (N/m) from CasADi's AD, shape ``(n, 3)``."""
    if not isinstance(soil, Soil):
        raise DataError(
            f"soil must be a Soil (sensitivities to c and phi at a ridge point are meaningless), "
            f"got {type(soil).__name__}"
        )
    shape, args = _args(slip, soil, vehicle, normal_load)
    if args[0].size == 0:
        return np.zeros((0, 3))
    out = np.asarray(_mapped("dF", check_model(model), args[0].size)(*args), dtype=float)
    return out.reshape(-1, 3)  # mapped call: 1 x 3n, one [c, phi, K] block per point


def max_thrust(soil, vehicle: Vehicle, model: str | None = None, normal_load=None) -> float | np.ndarray:
    """Soil thrust limit ``F_max = A c + W tan(phi)`` in N (cohesion-free: ``W tan(phi)``).

    ``soil`` is a :class:`Soil` or a fit result (see :func:`tractive_force`).
    """
    soil, model = resolve_soil(soil, vehicle, model, normal_load)
    W = vehicle.weight if normal_load is None else np.asarray(normal_load, dtype=float)
    F = max_thrust_expr(soil.cohesion, soil.friction_angle, W, vehicle.contact_area, model)
    return F if np.ndim(F) else float(F)
