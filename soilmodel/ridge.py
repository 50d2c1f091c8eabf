"""The c-phi ridge: at one normal load, c and phi enter only through ``F_max = A c + N tan(phi)``.

One home for what follows from that (docs/paper.md): the range of F_max a bounds box
allows, the centre of the bounds-feasible ridge (the one marker every engine reports for
one-load data, labelled as NOT an estimate), and the ranges of c and phi along the ridge for
an interval of F_max. ``N`` is the actual normal load (the nominal W, or W with effects).
F_max itself is :func:`~soiltrack.soilmodel.traction.max_thrust_expr`.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from .soil import SoilBounds
from .traction import max_thrust_expr

__all__ = [
    "corner_soils",
    "soil_fmax_range",
    "fmax_range",
    "ridge_centre",
    "ridge_ranges",
    "one_load",
    "LOAD_RTOL",
    "distinct_loads",
    "MAX_LOAD_LEVELS",
    "continuous_load",
    "load_summary_points",
]

#: Relative tolerance below which two normal loads are the same load (one home for "one load").
LOAD_RTOL = 1e-9
#: Up to this many distinct normal loads are load levels (a designed test: each is reported and
#: drawn on its own); more are a measured load varying from row to row - a continuous covariate,
#: reported and drawn by range (its median row's load and its extremes).
MAX_LOAD_LEVELS = 3


def continuous_load(W) -> bool:
    """Whether the normal loads are a continuous covariate (more than :data:`MAX_LOAD_LEVELS` distinct)."""
    return distinct_loads(W).size > MAX_LOAD_LEVELS


def load_summary_points(W) -> np.ndarray:
    """The loads to report a continuous load at: the lowest, the median row's and the highest (sorted).

    For load levels (see :func:`continuous_load`): every distinct load.
    """
    levels = distinct_loads(W)
    if levels.size <= MAX_LOAD_LEVELS:
        return levels
    w = np.sort(np.asarray(W, dtype=float).ravel())
    return np.array([levels[0], w[w.size // 2], levels[-1]])


def distinct_loads(W) -> np.ndarray:
    """Distinct normal loads (sorted, finite), two loads being equal within :data:`LOAD_RTOL`."""
    if type(W) is np.ndarray and W.ndim == 1 and W.dtype == np.float64:
        w = W
    else:
        w = np.atleast_1d(np.asarray(W, dtype=float)).ravel()
    if w.size and math.isfinite(w[0]) and not np.count_nonzero(w != w[0]):  # one load (the common case)
        return w[:1].copy()
    w = np.sort(w[np.isfinite(w)])
    if w.size == 0:
        return w
    keep = np.concatenate([[True], np.diff(w) > LOAD_RTOL * np.abs(w[1:])])
    return w[keep]


def one_load(W) -> bool:
    """Whether all normal loads are one load (within :data:`LOAD_RTOL`): the c-phi ridge case."""
    return distinct_loads(W).size == 1


def fmax_range(N: float, A: float, bounds: SoilBounds) -> tuple[float, float]:
    """``[A c_lo + N tan(phi_lo), A c_hi + N tan(phi_hi)]``: the F_max the box allows (full model)."""
    (c_lo, c_hi), (p_lo, p_hi) = bounds.cohesion, bounds.friction_angle
    return float(max_thrust_expr(c_lo, p_lo, N, A)), float(max_thrust_expr(c_hi, p_hi, N, A))


def ridge_centre(fmax, W, A: float, bounds: SoilBounds):
    """Centre of the bounds-feasible c-phi ridge ``A c + W tan(phi) = F_max`` (vectorised).

    At one normal load every point of this segment fits the data equally well; the library
    reports its centre (labelled as NOT an estimate) so that every engine - IPOPT, the
    compiled path, the batch engine - returns the same marker for the same data. Where the
    segment is empty (F_max outside what the box allows) the nearest feasible point is used.
    Returns ``(c, phi)`` in Pa and rad, shaped like ``fmax``.
    """
    F = np.asarray(fmax, dtype=float)
    W = np.asarray(W, dtype=float)
    (c_lo, c_hi), (p_lo, p_hi) = bounds.cohesion, bounds.friction_angle
    c_a = np.maximum(c_lo, (F - max_thrust_expr(0.0, p_hi, W, A)) / A)
    c_b = np.minimum(c_hi, (F - max_thrust_expr(0.0, p_lo, W, A)) / A)
    c = np.where(c_a <= c_b, 0.5 * (c_a + c_b), np.clip(c_a, c_lo, c_hi))
    phi = np.clip(np.arctan(np.maximum(F - A * c, 0.0) / W), p_lo, p_hi)
    return c, phi


def ridge_ranges(F_lo: float, F_hi: float, N: float, A: float, bounds: SoilBounds):
    """Ranges ``((c_a, c_b), (phi_a, phi_b))`` of the ridge points with F_max in ``[F_lo, F_hi]``
    inside the box, or ``None`` when no such point lies within the bounds."""
    (c_lo, c_hi), (p_lo, p_hi) = bounds.cohesion, bounds.friction_angle
    c_a = max(c_lo, (F_lo - max_thrust_expr(0.0, p_hi, N, A)) / A)
    c_b = min(c_hi, (F_hi - max_thrust_expr(0.0, p_lo, N, A)) / A)
    ph_a = max(p_lo, math.atan((F_lo - A * c_hi) / N))
    ph_b = min(p_hi, math.atan((F_hi - A * c_lo) / N))
    if c_a > c_b or ph_a > ph_b:
        return None
    return (float(c_a), float(c_b)), (float(ph_a), float(ph_b))


def corner_soils(bounds: SoilBounds, model: str) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """``[c, phi, K]`` (SI) of the weakest (c, phi low, K high) and strongest (c, phi high, K low) soil
    within the bounds (c = 0 for the cohesion-free model)."""
    try:
        return _corner_soils(bounds, model)
    except TypeError:  # unhashable bounds: not cached
        return _corner_soils.__wrapped__(bounds, model)


@lru_cache(maxsize=64)
def _corner_soils(bounds: SoilBounds, model: str) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    cf = model == "cohesion-free"
    return (
        (0.0 if cf else float(bounds.cohesion[0]), float(bounds.friction_angle[0]), float(bounds.shear_modulus[1])),
        (0.0 if cf else float(bounds.cohesion[1]), float(bounds.friction_angle[1]), float(bounds.shear_modulus[0])),
    )


def soil_fmax_range(bounds: SoilBounds, vehicle, model: str, normal_load: float) -> tuple[float, float]:
    """Smallest and largest thrust limit F_max (N) that soils within the bounds give at this load (``model``:
    full or cohesion-free; ``vehicle``: anything with a ``contact_area``)."""
    key = (bounds, vehicle.contact_area, model, float(normal_load))
    try:
        return _fmax_range(*key)
    except TypeError:  # unhashable bounds: not cached
        return _fmax_range.__wrapped__(*key)


@lru_cache(maxsize=1024)
def _fmax_range(bounds: SoilBounds, A: float, model: str, W: float) -> tuple[float, float]:
    weak, strong = corner_soils(bounds, model)
    return float(max_thrust_expr(weak[0], weak[1], W, A, model)), float(
        max_thrust_expr(strong[0], strong[1], W, A, model)
    )
