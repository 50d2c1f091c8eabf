"""The weights of the held-torque discretisation of the sprocket equation (slip relaxation within a sample).

With the torque held from one sample to the next, the discrete sprocket equation gives the MEAN
thrust over each interval, ``T_k = (M_{k-1} - I (w_k - w_{k-1}) / h) / r``, while the slip and the
model's thrust ``F(i_k)`` belong to the sample instant. After each torque step the slip relaxes with
the time constant ``tau = I w / ((1 - i) r dF/di)``; when ``tau`` is not small against the sample
interval (the light vehicle at 50 Hz, slips of a few percent: tau about 4 ms against 20 ms; on the
flat of the curve far more), the interval's mean lags its end. Measured on a noise-free simulated log
of hard pulls (light vehicle, LETE sand, 50 Hz): the end-point rule put F_max 3.3 % high, 10
standard errors, and the error halved with each doubling of the rate (25 to 200 Hz: +10.0, +3.3,
+2.0, +0.9 %).

The thrust at sample k is therefore taken as ``(1 - phi_k) T_k + phi_k T_{k+1}`` with
``phi_k = phi(h / tau_k)`` (:func:`~soiltrack.soilmodel.dynamics.held_torque_weight_expr`), which
cancels the lag to first order in the change of the thrust; ``tau_k`` from the soil's thrust law at
a pilot estimate of (F_lim, K) and the measured slip (the weight is a property of the
discretisation, not a fitted quantity). This module computes the weights; :mod:`.prepare` mixes the
rows.
"""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np

from ...soilmodel.dynamics import held_torque_stencil_expr, held_torque_weight_expr, slip_time_constant_expr
from ...soilmodel.effects import thrust_with_effects
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.vehicle import Vehicle

__all__ = [
    "DISCRETISATIONS",
    "RELAXATION_CURVATURE",
    "RELAXATION_SLIP_RANGE",
    "RELAXATION_SPREAD",
    "TREND_SAMPLES",
    "relaxation_function",
    "relaxation_stencil",
    "relaxation_weights",
    "slip_trend",
]

#: The discretisations of the held-torque sprocket equation: ``"end-point"`` (default: the interval's
#: mean thrust put on its end slip, the quasi-static limit) and ``"relaxation"`` (the thrust at the
#: sample from two interval means with the slip-relaxation weight). Neither is better everywhere
#: (``python benchmarks/drivelog_discretisation.py``): on hard pulls the end-point rule puts F_max high
#: and its intervals miss (8 deg, 50 Hz: 8 of 20 hold the truth; relaxation 20 of 20), on the default
#: profile the relaxation weights give intervals too narrow (60 seeds: F_max 52, K 49 of 60 against
#: 56 and 55) and F_max 0.5 % higher. Why is not established: the mix correlates neighbouring samples,
#: but adding the lag-1 cross products of the scores to the sandwich made it worse (49 and 49 of 60).
DISCRETISATIONS = ("end-point", "relaxation")
#: Samples of the running median that gives the slip a weight is computed at. The weight multiplies the
#: difference of two interval means, which holds the encoder noise of the sample's own sprocket speed;
#: a weight from the sample's own measured slip (which holds the same noise) would correlate with it
#: and bias the mixed thrust (measured: F_max +0.8 % instead of +0.3 % on the default profile, 20
#: seeds). The median of 11 samples describes the slip's trend and dilutes that noise elevenfold.
TREND_SAMPLES = 11
#: The factor of the curvature term of the relaxation rule (:func:`~soiltrack.soilmodel.dynamics.
#: held_torque_stencil_expr`): 2/3 makes it, where the slip relaxes slowly (near the traction limit), the
#: fourth-order reconstruction of the thrust at a sample from interval means around it; 0 is the first-order
#: rule ``(1 - phi) T_k + phi T_{k+1}``, which on the independent simulator's noise-free hard pulls put F_max
#: 0.36 % low at 50 Hz (5 min, seeds 1-2; 2/3 with the spread 1: -0.09 %; docs/drivelogs.md).
RELAXATION_CURVATURE = 2.0 / 3.0
#: Offset ``s`` of the outer interval means of the curvature term (``T_{k-s}`` and ``T_{k+1+s}``); the term is
#: used where every second difference of the interval means inside that window is within the noise (else the
#: first-order rule). Chosen on the independent simulator's noisy tuning logs (10 min, seeds 1-8, F_max error
#: over seeds): 1 gives +0.44 % +- 0.11 (why is not established), 3 gives -0.02 % +- 0.11, 6
#: -0.19 % +- 0.11 (the term then hardly used: the first-order rule's -0.19 %). An empirical choice: without
#: noise the spread 3 leaves the first-order rule's -0.30 % (the window's test then rejects most pull samples).
RELAXATION_SPREAD = 3
#: Measured slips are clipped to this range for the weight (the curve's slope at the slip).
RELAXATION_SLIP_RANGE = (1e-4, 0.95)


def slip_trend(slip: np.ndarray, samples: int = TREND_SAMPLES) -> np.ndarray:
    """Running median of ``slip`` over ``samples`` (odd) consecutive samples, NaN-aware, same length."""
    x = np.asarray(slip, dtype=float)
    half = samples // 2
    if x.size == 0:
        return x.copy()
    padded = np.pad(x, half, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    with warnings.catch_warnings():  # an all-NaN window (a long dropout) keeps the sample's own value
        warnings.simplefilter("ignore", RuntimeWarning)
        out = np.nanmedian(np.where(np.isfinite(windows), windows, np.nan), axis=1)
    return np.where(np.isfinite(out), out, x)


@locked_cache(maxsize=16)
def relaxation_function(vehicle: Vehicle) -> ca.Function:
    """``(F_lim, K, slip, w, h) -> phi``: the weight of one sample (the cohesion-free law at F_lim)."""
    Flim, K, slip, w, h = (ca.SX.sym(s) for s in ("F_lim", "K", "slip", "w", "h"))
    W = vehicle.weight
    F = thrust_with_effects(slip, 0.0, ca.atan(Flim / W), K, W, vehicle, None, "cohesion-free")
    tau = slip_time_constant_expr(slip, w, ca.jacobian(F, slip), vehicle)
    return ca.Function("held_torque_weight", [Flim, K, slip, w, h], [held_torque_weight_expr(h / tau)])


@locked_cache(maxsize=16)
def _stencil_function(vehicle: Vehicle, curvature: float, spread: int) -> ca.Function:
    """``(F_lim, K, slip, w, h) -> (c_-1, c_0, c_1, c_2)``: the relaxation rule's weights of one sample."""
    Flim, K, slip, w, h = (ca.SX.sym(s) for s in ("F_lim", "K", "slip", "w", "h"))
    W = vehicle.weight
    F = thrust_with_effects(slip, 0.0, ca.atan(Flim / W), K, W, vehicle, None, "cohesion-free")
    tau = slip_time_constant_expr(slip, w, ca.jacobian(F, slip), vehicle)
    phi = ca.fmin(ca.fmax(held_torque_weight_expr(h / tau), 0.0), 0.5)
    weights = held_torque_stencil_expr(h / tau, curvature, spread)
    return ca.Function("held_torque_stencil", [Flim, K, slip, w, h], [phi, ca.vertcat(*weights)])


def relaxation_stencil(
    vehicle: Vehicle,
    max_thrust: float,
    shear_modulus: float,
    slip: np.ndarray,
    w: np.ndarray,
    h: np.ndarray,
    curvature: float = RELAXATION_CURVATURE,
    spread: int = RELAXATION_SPREAD,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample weight ``phi`` and the rule's four weights (n x 4) of ``T_{k-s}, T_k, T_{k+1}, T_{k+1+s}``.

    As :func:`relaxation_weights` for ``phi`` (the same clipping); the weights are those of
    :func:`~soiltrack.soilmodel.dynamics.held_torque_stencil_expr` with ``curvature`` and ``spread``.
    """
    slip = np.clip(np.nan_to_num(np.asarray(slip, dtype=float), nan=RELAXATION_SLIP_RANGE[0]), *RELAXATION_SLIP_RANGE)
    n = slip.size
    if n == 0:
        return np.zeros(0), np.zeros((0, 4))
    fn = _stencil_function(vehicle, float(curvature), int(spread)).map(n)
    phi, c = fn(max_thrust, shear_modulus, slip, np.asarray(w, dtype=float), np.asarray(h, dtype=float))
    phi = np.nan_to_num(np.asarray(phi, dtype=float).ravel(), nan=0.0)
    c = np.asarray(c, dtype=float).T
    bad = ~np.all(np.isfinite(c), axis=1)
    c[bad] = (0.0, 1.0, 0.0, 0.0)  # the end-point rule where the weight is undefined
    return phi, c


def relaxation_weights(
    vehicle: Vehicle, max_thrust: float, shear_modulus: float, slip: np.ndarray, w: np.ndarray, h: np.ndarray
) -> np.ndarray:
    """Per-sample weights ``phi`` in [0, 1/2] of the next interval's mean thrust.

    Parameters
    ----------
    vehicle
        The vehicle (sprocket radius and inertia, track length).
    max_thrust, shear_modulus
        The thrust limit at the log's load (N) and K (m) of the pilot estimate.
    slip, w, h
        Measured slip, sprocket speed (rad/s) and sample interval (s) per sample.
    """
    slip = np.clip(np.nan_to_num(np.asarray(slip, dtype=float), nan=RELAXATION_SLIP_RANGE[0]), *RELAXATION_SLIP_RANGE)
    n = slip.size
    if n == 0:
        return np.zeros(0)
    fn = relaxation_function(vehicle).map(n)
    phi = np.asarray(fn(max_thrust, shear_modulus, slip, np.asarray(w, dtype=float), np.asarray(h, dtype=float)))
    return np.clip(np.nan_to_num(phi.ravel(), nan=0.0), 0.0, 0.5)
