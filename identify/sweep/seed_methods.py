"""The seed paper's two methods, implemented honestly: Newton-Raphson and least squares.

``newton``
    Newton-Raphson on the square system of Eq. 5, ``f_k(c, phi, K) = F(i_k) - F_k = 0``,
    with the step ``-J^{-1} f`` of Eq. 7, in scaled variables (c in kPa, phi in rad, K in cm).
    It needs exactly as many samples as free parameters (3 full, 2 cohesion-free); with
    more samples the same iteration uses the least-squares step ``-J^+ f`` (Gauss-Newton),
    which is said in the result's message. No bounds (the seed has none). Before every
    step the column-scaled Jacobian is checked: condition number above ``1e10`` (or
    non-finite entries) stops the iteration with status ``Singular_Jacobian`` - which is
    what happens for the full model at a single normal load, where the c and phi columns are
    exactly proportional. Non-finite steps, leaving the physical domain
    (phi outside (0, 90) deg, K <= 0), growth of the residual by 1e6 and the iteration cap
    are failures too. A failed result carries no estimate (values ``None``).

``least-squares``
    Unconstrained Levenberg-Marquardt (Marquardt 1963: damping ``lambda * diag(J^T J)``,
    ``lambda`` starting at 1e-3, times 10 on a rejected step, divided by 10 on an accepted one)
    on the weighted residuals of Eq. 2, in the same scaled variables, no bounds. Steps that
    leave the physical domain are rejected like cost increases. Converged when the relative
    cost decrease and the scaled step are below 1e-12 (or the gradient vanishes). On
    rank-deficient data (one normal load) the damping makes it stop at SOME point of the
    c-phi ridge; :func:`~soiltrack.identify.estimates.result.build_result` reports that point as not
    identifiable. A negative cohesion is outside the physical domain: reported as a failure.
"""

from __future__ import annotations

import time

import numpy as np

from .problem import SCALE, SlipProblem
from ..estimates.result import FitResult
from .start import middle_of_bounds, start_point

__all__ = ["fit_newton", "fit_least_squares", "default_start"]

COND_MAX = 1e10


def default_start(pb: SlipProblem) -> np.ndarray:
    """Middle of the bounds (the seed's initial guess is not given)."""
    return middle_of_bounds(pb.bounds, "full")


def _in_domain(theta: np.ndarray) -> bool:
    return bool(np.all(np.isfinite(theta)) and 0 < theta[1] < np.pi / 2 and theta[2] > 0)


def _scaled_cond(J: np.ndarray) -> float:
    if not np.all(np.isfinite(J)):
        return np.inf
    nrm = np.linalg.norm(J, axis=0)
    if np.any(nrm == 0):
        return np.inf
    s = np.linalg.svd(J / nrm, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else np.inf


def _start(pb: SlipProblem, x0) -> np.ndarray:
    """The start vector ``[c, phi, K]`` (the bounds' middle unless given; c = 0 for cohesion-free)."""
    return start_point(pb, x0, "middle")[0]


def fit_newton(pb: SlipProblem, x0=None, max_iter: int = 50, tol: float = 1e-12) -> FitResult:
    """Newton-Raphson (square system) / Gauss-Newton (more samples), unbounded; see module docs."""
    t0 = time.perf_counter()
    free = pb.free
    theta = _start(pb, x0)
    square = pb.n == len(free)
    kind = (
        "Newton-Raphson on the square system (Eq. 5-7)"
        if square
        else f"Gauss-Newton (least-squares step, {pb.n} samples > {len(free)} unknowns)"
    )
    status, ok, msg = "Maximum_Iterations_Exceeded", False, f"no convergence in {max_iter} iterations"
    f0 = None
    it = 0
    cond = np.nan
    for it in range(1, max_iter + 1):
        _, rw, J = pb.residuals(theta)
        Js = J[:, free] * SCALE[free]
        fnorm = float(np.linalg.norm(rw))
        f0 = fnorm if f0 is None else f0
        if not np.isfinite(fnorm):
            status, msg = "Non_Finite_Residual", "the residual became non-finite"
            break
        if fnorm > 1e6 * max(f0, 1e-300):
            status, msg = "Diverged", f"the residual grew by more than 1e6 (iteration {it})"
            break
        cond = _scaled_cond(Js)
        if not np.isfinite(cond) or cond > COND_MAX:
            status = "Singular_Jacobian"
            msg = (
                f"the Jacobian is singular (column-scaled condition number {cond:.3g} > {COND_MAX:.0e}) at "
                f"iteration {it}: no Newton step exists"
            )
            if pb.model == "full" and np.unique(pb.load).size == 1:
                msg += (
                    "; c and phi enter Eq. 2 only through F_max = A c + W tan(phi) at one normal load, so their "
                    "Jacobian columns are proportional (use method='ipopt', which reports F_max and K)"
                )
            break
        if square:
            step = np.linalg.solve(Js, -rw)
        else:
            step = np.linalg.lstsq(Js, -rw, rcond=None)[0]
        if not np.all(np.isfinite(step)):
            status, msg = "Non_Finite_Step", "the Newton step is not finite"
            break
        new = theta.copy()
        new[free] = theta[free] + step * SCALE[free]
        if not _in_domain(new):
            status, msg = (
                "Left_Physical_Domain",
                (f"the Newton step left the physical domain (phi in (0, 90) deg, K > 0) at iteration {it}"),
            )
            break
        theta = new
        z = theta[free] / SCALE[free]
        if np.linalg.norm(step) <= tol * (1.0 + np.linalg.norm(z)):
            status, ok, msg = "Converged", True, f"converged: {kind}"
            break
    if ok and pb.model == "full" and theta[0] < 0:
        ok, status = False, "Nonphysical_Solution"
        msg = f"converged to a negative cohesion ({theta[0] / 1e3:.4g} kPa): no physical solution"
    dt = time.perf_counter() - t0
    return pb.result(
        theta,
        method="newton",
        status=status,
        success=ok,
        message=msg,
        iterations=it,
        solve_time=dt,
        extra={"algorithm": kind, "condition_number": float(cond) if np.isfinite(cond) else None},
    )


def fit_least_squares(pb: SlipProblem, x0=None, max_iter: int = 500, tol: float = 1e-12) -> FitResult:
    """Unconstrained Levenberg-Marquardt on Eq. 2 (the seed's comparison method); see module docs."""
    t0 = time.perf_counter()
    free = pb.free
    theta = _start(pb, x0)
    lam = 1e-3
    _, rw, J = pb.residuals(theta)
    cost = 0.5 * float(rw @ rw)
    status, ok, msg = "Maximum_Iterations_Exceeded", False, f"no convergence in {max_iter} iterations"
    it = 0
    for it in range(1, max_iter + 1):
        Js = J[:, free] * SCALE[free]
        g = Js.T @ rw
        H = Js.T @ Js
        if not (np.all(np.isfinite(H)) and np.all(np.isfinite(g))):
            status, msg = "Non_Finite_Jacobian", "the Jacobian became non-finite"
            break
        if np.linalg.norm(g) <= 1e-14 * max(1.0, float(np.linalg.norm(rw) * np.linalg.norm(Js))):
            status, ok, msg = "Converged", True, "gradient vanished"
            break
        accepted = False
        while lam < 1e16:
            A = H + lam * np.diag(np.maximum(np.diag(H), 1e-30 * max(np.trace(H), 1e-300)))
            try:
                step = np.linalg.solve(A, -g)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            new = theta.copy()
            new[free] = theta[free] + step * SCALE[free]
            if _in_domain(new):
                _, rw_new, J_new = pb.residuals(new)
                c_new = 0.5 * float(rw_new @ rw_new)
                if np.isfinite(c_new) and c_new <= cost:
                    accepted = True
                    break
            lam *= 10
        if not accepted:
            status, ok, msg = "Converged", True, "no further decrease possible (damping at its cap)"
            break
        rel = (cost - c_new) / max(cost, 1e-300)
        small = np.linalg.norm(step) <= tol * (1 + np.linalg.norm(theta[free] / SCALE[free]))
        theta, rw, J, cost = new, rw_new, J_new, c_new
        lam = max(lam / 10, 1e-12)
        if rel <= tol and small:
            status, ok, msg = "Converged", True, "relative cost decrease and step below 1e-12"
            break
    if ok and pb.model == "full" and theta[0] < 0:
        ok, status = False, "Nonphysical_Solution"
        msg = f"converged to a negative cohesion ({theta[0] / 1e3:.4g} kPa): outside the physical domain"
    dt = time.perf_counter() - t0
    return pb.result(
        theta,
        method="least-squares",
        status=status,
        success=ok,
        message=f"unconstrained Levenberg-Marquardt (Marquardt damping), {msg}",
        iterations=it,
        solve_time=dt,
        extra={"algorithm": "unconstrained Levenberg-Marquardt, diag(J^T J) damping, scaled variables (kPa, rad, cm)"},
    )
