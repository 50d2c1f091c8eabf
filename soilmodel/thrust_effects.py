"""Tractive force with the effects that change it: strain-softening shear, non-uniform pressure, load.

Hump shear, the parametrisation
-------------------------------
Wong's type B form (docs/physics.md),
``tau/tau_max = K_r {1 + [1/(K_r (1 - 1/e)) - 1] exp(1 - j/K_w)} (1 - exp(-j/K_w))``, does not
contain Janosi-Hanamoto as a special case (K_r = 1 still gives a hump of about 5 %), so it
cannot be an augmentation whose "off" value is the nominal model. The library uses the nested
strain-softening form::

    s(j) = (1 - exp(-j/K)) * [1 - drop * (1 - exp(-j/K_s))],   K_s = k_ratio * K

``drop = 0`` is Janosi-Hanamoto exactly; for ``0 < drop < 1`` and ``k_ratio > 1`` the shear
stress rises with modulus K, peaks, then falls to the residual fraction ``1 - drop`` of the
Mohr-Coulomb strength over the longer displacement scale K_s: the shape of type B (peak then
residual). Over the track this gives a closed form (``g(X) = 1 - (1 - exp(-X))/X``, the
Janosi-Hanamoto slip factor of :func:`~.traction.slip_factor`, ``X = |i| l / K``)::

    mean over the track of s = g(X) - drop * [g(X) + g(X / k_ratio) - g(X (1 + 1/k_ratio))]

:func:`wong_type_b_shear` gives Wong's form itself for comparison.

Pressure distribution, the closed form
--------------------------------------
With ``beta = |i| / K`` and ``X = beta l``, the mean over the track of the three pressure
shapes times ``1 - exp(-beta x)`` is ``g(X)`` (uniform), ``m1(X) = (1 - e^-X)/X -
2 (1 - e^-X (1 + X))/X^2`` (linear shift; series below X = 1) and
``mc(X) = -(1 - e^-X) X / (X^2 + (2 pi n_w)^2)`` (cosine, exact for integer ``n_w``). Hence::

    F = sign(i) [(A c + N tan(phi)) g(X) + N tan(phi) (e m1(X) + alpha mc(X))]

Cohesion is a property of the soil, not of the pressure, so only the friction part changes.
The cosine has ``n_w`` periods along the track: peaks at ``x = k l / n_w``, ``k = 0..n_w``.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from .effect_registry import EffectSet, EffectValues, parse_effects
from .effect_terms import effective_normal_load
from .soil import Soil
from .traction import check_model, max_thrust_expr, slip_factor, thrust_expr
from .vehicle import Vehicle

__all__ = [
    "thrust_with_effects",
    "thrust_with_effects_function",
    "tractive_force_with_effects",
    "softening_shear",
    "wong_type_b_shear",
    "pressure_profile",
]


def _horner(coefs, x):
    out = 0.0
    for c in reversed(coefs):
        out = c + x * out
    return out


#: Taylor coefficients of m1(X) = sum_k -(-1)^k k / ((k+1)(k+2) k!) X^k, k = 0..20.
_M1_COEFS = [-((-1) ** k) * k / ((k + 1) * (k + 2) * math.factorial(k)) for k in range(21)]
_M1_SWITCH = 1.0


def _m1(X):
    """Mean over the track of (2x/l - 1)(1 - exp(-X x/l)), extended as an odd function of X.

    Series below |X| = 1 (no cancellation), written with X and |X| so that automatic
    differentiation gives the true slope 1/6 at X = 0.
    """
    a = ca.fabs(X)
    series = 0.0
    for k in range(len(_M1_COEFS) - 1, 0, -1):  # sum_k c_k sign(X) |X|^k, Horner in |X|
        series = _M1_COEFS[k] + a * series
    series = X * series
    safe = ca.if_else(a < _M1_SWITCH, 1.0, a)
    one_minus = -ca.expm1(-safe)
    exact = ca.sign(X) * (one_minus / safe - 2 * (one_minus - safe * ca.exp(-safe)) / (safe * safe))
    return ca.if_else(a < _M1_SWITCH, series, exact)


def _mc(X, n_w):
    """Mean over the track of cos(2 pi n_w x/l)(1 - exp(-X x/l)), odd in X, integer n_w (exact, finite at 0)."""
    w = 2 * math.pi * n_w
    return -(-ca.expm1(-ca.fabs(X))) * X / (X * X + w * w)


def thrust_with_effects(slip, c, phi, K, W, vehicle: Vehicle, effects: Any = None, model: str = "full"):
    """Tractive force of both tracks with the effects that change it (symbolic), N.

    ``F = 2 b * integral over the track of (c + p(x) tan(phi)) s(i x) dx`` in closed form, with
    ``s`` the shear law (Janosi-Hanamoto, or :func:`softening_shear` for ``hump_shear``) and
    ``p`` the pressure (uniform, or :func:`pressure_profile` for ``pressure_distribution``).
    The normal load is the actual one, ``W (1 + delta) cos(theta)`` (``mass_error``,
    ``grade``). Skid: ``F(i) = -F(|i|)`` (every term is an odd function of the slip).
    ``F(0) = 0`` with exact derivatives (series near 0). With no shear-changing effect on this
    is :func:`~.traction.thrust_expr` itself.

    Parameters
    ----------
    slip, c, phi, K
        Track slip (-), cohesion (Pa), friction angle (rad), shear modulus (m): floats or CasADi.
    W
        NOMINAL normal load, N (e.g. ``vehicle.weight``, or a rig's set load).
    vehicle
        Gives l, b (and r, road wheels).
    effects
        An :class:`EffectSet`, anything :func:`parse_effects` accepts, or a mapping
        ``{effect: {param: value-or-symbol}}`` (see :func:`effect_symbols`).
    model
        ``"full"`` or ``"cohesion-free"`` (drops ``A c``).
    """
    check_model(model)
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    N = effective_normal_load(W, vehicle, ev)
    l, b = vehicle.track_length, vehicle.track_width
    if not (ev.on("hump_shear") or ev.on("pressure_distribution")):
        return thrust_expr(slip, c, phi, K, N, l, b, model)
    f_max = max_thrust_expr(c, phi, N, 2 * b * l, model)
    fric = N * ca.tan(phi)

    def mean(K_):
        """Force of the shear law 1 - exp(-|i| x / K_) under the (possibly non-uniform) pressure."""
        out = f_max * slip_factor(slip, l, K_)
        if ev.on("pressure_distribution"):
            X = slip * l / K_
            out = out + fric * (
                ev["pressure_distribution", "e"] * _m1(X)
                + ev["pressure_distribution", "alpha"] * _mc(X, ev["pressure_distribution", "n_w"])
            )
        return out

    total = mean(K)
    if ev.on("hump_shear"):
        drop, kr = ev["hump_shear", "drop"], ev["hump_shear", "k_ratio"]
        # s = (1 - u)(1 - drop (1 - u_s)) = (1 - u) - drop [(1 - u) + (1 - u_s) - (1 - u u_s)]
        total = total - drop * (total + mean(K * kr) - mean(K * kr / (1 + kr)))
    return total


@lru_cache(maxsize=256)
def _thrust_fn(vehicle: Vehicle, effects: EffectSet, model: str) -> ca.Function:
    s = [ca.SX.sym(n) for n in ("slip", "c", "phi", "K", "W")]
    F = thrust_with_effects(s[0], s[1], s[2], s[3], s[4], vehicle, effects, model)
    return ca.Function("thrust_effects", s, [F], ["slip", "c", "phi", "K", "W"], ["F"])


def thrust_with_effects_function(vehicle: Vehicle, effects: Any = None, model: str = "full") -> ca.Function:
    """Cached CasADi Function ``F(slip, c, phi, K, W)`` (W nominal) with numeric effects."""
    check_model(model)
    return _thrust_fn(vehicle, parse_effects(effects), model)


def tractive_force_with_effects(
    slip, soil: Soil, vehicle: Vehicle, effects: Any = None, model: str = "full", normal_load=None
) -> np.ndarray:
    """Numpy tractive force (N) with effects, shaped like the broadcast of ``slip`` and ``normal_load``.

    ``normal_load`` is the nominal load (default the vehicle's weight).
    """
    W = vehicle.weight if normal_load is None else normal_load
    s, Wb = np.broadcast_arrays(np.asarray(slip, dtype=float), np.asarray(W, dtype=float))
    if s.size == 0:
        return np.zeros(s.shape)
    f = thrust_with_effects_function(vehicle, effects, model)
    out = f(s.reshape(1, -1), soil.cohesion, soil.friction_angle, soil.shear_modulus, Wb.reshape(1, -1))
    return np.asarray(out, dtype=float).reshape(s.shape)


def softening_shear(j, K: float, drop: float = 0.0, k_ratio: float = 5.0) -> np.ndarray:
    """Normalised shear stress of the ``hump_shear`` law, ``tau / (c + p tan(phi))`` (numpy).

    ``s(j) = (1 - exp(-j/K)) [1 - drop (1 - exp(-j/(k_ratio K)))]``; ``drop = 0`` is
    Janosi-Hanamoto. Residual value ``1 - drop``.
    """
    j = np.asarray(j, dtype=float)
    return -np.expm1(-j / K) * (1 - drop * -np.expm1(-j / (k_ratio * K)))


def wong_type_b_shear(j, K_r: float, K_w: float) -> np.ndarray:
    """Wong's type B shear law ``tau / tau_max`` as written in docs/physics.md (numpy), for comparison.

    ``K_r {1 + [1/(K_r (1 - 1/e)) - 1] exp(1 - j/K_w)} (1 - exp(-j/K_w))``: equal to 1 at
    ``j = K_w`` (its normalisation; the exact maximum lies slightly before K_w and a few percent
    above 1 for K_r < 1), tending to the residual ``K_r``.
    """
    j = np.asarray(j, dtype=float)
    amp = 1.0 / (K_r * (1.0 - math.exp(-1.0))) - 1.0
    return K_r * (1.0 + amp * np.exp(1.0 - j / K_w)) * -np.expm1(-j / K_w)


def pressure_profile(x, vehicle: Vehicle, effects: Any = None, W=None) -> np.ndarray:
    """Normal pressure p(x) under one track, Pa, x from the front (numpy; uniform when off).

    ``p_mean = N / A`` with the actual normal load N.
    """
    ev = EffectValues(effects, vehicle)
    W = vehicle.weight if W is None else W
    p_mean = float(effective_normal_load(W, vehicle, ev)) / vehicle.contact_area
    x = np.asarray(x, dtype=float)
    l = vehicle.track_length
    shape = np.ones_like(x)
    if ev.on("pressure_distribution"):
        e, a, n = (float(ev["pressure_distribution", k]) for k in ("e", "alpha", "n_w"))
        shape = shape + e * (2 * x / l - 1) + a * np.cos(2 * math.pi * n * x / l)
    return p_mean * shape
