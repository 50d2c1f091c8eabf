"""From a bounded least-squares solution to reported parameters: the library's one record (SI inside,
built from the edge units the fit works in), intervals, bounds."""

from __future__ import annotations

import numpy as np

from ..estimates.distributions import t_ppf
from .lsq import BOUND_RTOL, LsqSolution, covariance
from ..estimates.records import NAME_OF_KEY, ParameterEstimate

__all__ = ["edge_parameters", "at_bounds", "CONFIDENCE"]

#: Level of the reported intervals (the JSON field is ``ci95``).
CONFIDENCE = 0.95


def at_bounds(x: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Which scaled parameters lie on a bound: within :data:`~.lsq.BOUND_RTOL` of it, relative to the
    box width or to 1 if smaller (the scaled parameters are of order one; a generous upper bound
    must not make a small value read as on its lower bound)."""
    tol = BOUND_RTOL * np.minimum(upper - lower, 1.0)
    return (x - lower <= tol) | (upper - x <= tol)


def edge_parameters(
    sol: LsqSolution,
    n_rows: int,
    values: np.ndarray,
    transform: np.ndarray,
    specs: list[tuple[str, str, str, float, float]],
    bound_flags: np.ndarray,
) -> tuple[list[ParameterEstimate], np.ndarray | None]:
    """Parameter records (SI; built from edge units) with linearised Student-t intervals clipped to their bounds.

    Parameters
    ----------
    sol
        The solution (scaled parameters ``x``, Jacobian, cost).
    n_rows
        Rows fitted.
    values
        The parameters in edge units at ``sol.x``.
    transform
        ``d values / d x`` at ``sol.x``.
    specs
        Per parameter ``(key, label, unit, lower, upper)`` in edge units (``key`` the JSON key of
        :data:`~soiltrack.identify.estimates.records.EDGE_UNITS`, whose unit is ``unit``).
    bound_flags
        Per parameter: on a bound (from :func:`at_bounds` of the scaled parameters it rests on).

    Returns
    -------
    parameters, covariance
        The :class:`~soiltrack.identify.estimates.records.ParameterEstimate` list, and the edge-unit
        covariance (``None`` without residual
        degrees of freedom).
    """
    cov_x, ident_x, dof = covariance(sol.jacobian, sol.cost, n_rows)
    ident = np.array([bool(np.all(ident_x[np.abs(transform[k]) > 0])) for k in range(len(values))])
    cov = None if cov_x is None else transform @ cov_x @ transform.T
    t = t_ppf(0.5 + CONFIDENCE / 2, dof) if dof > 0 else None
    out = []
    for k, (key, label, unit, lo, hi) in enumerate(specs):
        name = NAME_OF_KEY[key]
        if not ident[k]:
            why = "the data leave it undetermined (flat direction of the fit)"
            out.append(ParameterEstimate.from_edge(name, None, None, (None, None), False, note=why, label=label))
            continue
        v = float(values[k])
        side = ("lower" if v - lo <= hi - v else "upper") if bound_flags[k] else None
        kw = dict(at_bound=bool(bound_flags[k]), bound_side=side, lower=lo, upper=hi, label=label)
        if cov is None or t is None:
            note = "no residual degree of freedom: no interval"
            out.append(ParameterEstimate.from_edge(name, v, None, (None, None), True, note=note, **kw))
            continue
        se = float(np.sqrt(max(cov[k, k], 0.0)))
        ci = (max(lo, v - t * se), min(hi, v + t * se))
        note = "on a bound of its range" if bound_flags[k] else ""
        out.append(ParameterEstimate.from_edge(name, v, se, ci, True, note=note, **kw))
    return out, cov
