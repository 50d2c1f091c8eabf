"""From a bounded least-squares solution to reported parameters: edge units, intervals, bounds."""

from __future__ import annotations

import numpy as np

from ..estimates.distributions import t_ppf
from .lsq import BOUND_RTOL, LsqSolution, covariance
from .result import TestParameter

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
) -> tuple[list[TestParameter], np.ndarray | None]:
    """Parameters in edge units with linearised Student-t intervals (clipped to their bounds).

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
        Per parameter ``(key, label, unit, lower, upper)`` in edge units.
    bound_flags
        Per parameter: on a bound (from :func:`at_bounds` of the scaled parameters it rests on).

    Returns
    -------
    parameters, covariance
        The :class:`TestParameter` list, and the edge-unit covariance (``None`` without residual
        degrees of freedom).
    """
    cov_x, ident_x, dof = covariance(sol.jacobian, sol.cost, n_rows)
    ident = np.array([bool(np.all(ident_x[np.abs(transform[k]) > 0])) for k in range(len(values))])
    cov = None if cov_x is None else transform @ cov_x @ transform.T
    t = t_ppf(0.5 + CONFIDENCE / 2, dof) if dof > 0 else None
    out = []
    for k, (key, label, unit, lo, hi) in enumerate(specs):
        if not ident[k]:
            out.append(
                TestParameter(
                    key,
                    label,
                    unit,
                    None,
                    None,
                    (None, None),
                    False,
                    note="the data leave it undetermined (flat direction of the fit)",
                )
            )
            continue
        v = float(values[k])
        if cov is None or t is None:
            out.append(
                TestParameter(
                    key,
                    label,
                    unit,
                    v,
                    None,
                    (None, None),
                    True,
                    bool(bound_flags[k]),
                    note="no residual degree of freedom: no interval",
                    lower=lo,
                    upper=hi,
                )
            )
            continue
        se = float(np.sqrt(max(cov[k, k], 0.0)))
        ci = (max(lo, v - t * se), min(hi, v + t * se))
        out.append(
            TestParameter(
                key,
                label,
                unit,
                v,
                se,
                ci,
                True,
                bool(bound_flags[k]),
                note="on a bound of its range" if bound_flags[k] else "",
                lower=lo,
                upper=hi,
            )
        )
    return out, cov
