"""Core statistics of a least-squares fit: rank, covariance and degrees of freedom from the Jacobian.

* Columns of the Jacobian of the free parameters are scaled to unit norm (scale-free), and the
  scaled matrix is decomposed (SVD). Singular values below ``RANK_TOL`` times the largest are
  structural zeros: the rank is the number of identifiable directions.
* Covariance: ``s^2 (J^T J)^+`` (pseudo-inverse over the identifiable subspace). When
  ``sigma_known`` is false, ``s^2 = SSR / (n - rank)`` with ``SSR`` the sum of squared weighted
  residuals, and 95 % intervals use the Student t quantile with ``n - rank`` degrees of
  freedom; when true, ``s^2 = 1`` and the normal quantile. With ``n - rank = 0`` and unknown
  sigma no standard error exists.
"""

from __future__ import annotations

import numpy as np

from .distributions import norm_ppf, t_ppf

__all__ = [
    "RANK_TOL",
    "NULL_TOL",
    "WEAK_CORRELATION",
    "WEAK_VIF",
    "core_stats",
    "core_stats_one",
    "quantile",
    "identified_columns",
    "estimable",
]

#: Relative singular value (column-scaled Jacobian) below which a direction is unidentifiable.
RANK_TOL = 1e-8
#: Norm of a parameter's component in the null space (column-scaled coordinates) above which it is
#: not identifiable: the library's one such rule (track, wheel, bevameter tests, joint fits).
NULL_TOL = 1e-4
#: Multiple correlation above which a parameter or combination is called weakly identifiable.
WEAK_CORRELATION = 0.99
#: The variance inflation of :data:`WEAK_CORRELATION`.
WEAK_VIF = 1.0 / (1.0 - WEAK_CORRELATION**2)


def core_stats(J: np.ndarray, rw: np.ndarray, sigma_known: bool) -> dict[str, np.ndarray]:
    """Identifiability and covariance for a stack of fits (a single fit is a stack of one).

    J: (N, n, p) Jacobian of weighted residuals w.r.t. the FREE parameters; rw: (N, n).
    Returns arrays, all per fit: D (N,p) column scales, Dok (N,p) whether a column is usable,
    S (N,p) relative singular values (descending, zeros padded), V (N,p,p) right singular
    vectors (columns), rank (N,), Pinv (N,p,p) = (Js^T Js)^+ in scaled coordinates, ssr (N,),
    dof (N,), s2 (N,), nonnull (N,p). One thin SVD of the column-scaled Jacobian per fit.
    """
    J = np.asarray(J, dtype=float)
    N, n, p = J.shape
    D = np.sqrt(np.einsum("kij,kij->kj", J, J))
    ok = np.isfinite(D) & (D > 0)
    if ok.all():  # finite column norms: J is finite
        Dsafe = D
        Js = J / D[:, None, :]
    else:
        Dsafe = np.where(ok, D, 1.0)
        Js = np.where(ok[:, None, :], J / Dsafe[:, None, :], 0.0)
        Js = np.where(np.isfinite(Js), Js, 0.0)
    _, S, Vt = np.linalg.svd(Js, full_matrices=n < p)
    if S.shape[1] < p:
        S = np.concatenate([S, np.zeros((N, p - S.shape[1]))], axis=1)
    smax = S[:, :1]
    Srel = np.where(smax > 0, S / np.where(smax > 0, smax, 1.0), 0.0)
    nonnull = Srel > RANK_TOL
    rank = nonnull.sum(axis=1)
    inv2 = np.where(nonnull, 1.0 / np.where(nonnull, S, 1.0) ** 2, 0.0)
    V = np.swapaxes(Vt, 1, 2)
    Pinv = np.einsum("kij,kj,klj->kil", V, inv2, V)
    rw = np.asarray(rw, dtype=float)
    ssr = np.einsum("ki,ki->k", rw, rw)
    ssr = np.where(np.isfinite(ssr), ssr, np.nan)
    dof = n - rank
    if sigma_known:
        s2 = np.ones(N)
    else:
        s2 = np.where(dof > 0, ssr / np.maximum(dof, 1), np.nan)
    return {
        "D": Dsafe,
        "Dok": ok,
        "S": Srel,
        "V": V,
        "rank": rank,
        "Pinv": Pinv,
        "ssr": ssr,
        "dof": dof,
        "s2": s2,
        "nonnull": nonnull,
    }


def core_stats_one(J: np.ndarray, rw: np.ndarray, sigma_known: bool) -> dict[str, np.ndarray]:
    """:func:`core_stats` for ONE fit (J: (n, p), rw: (n,)): a stack of one."""
    return core_stats(np.asarray(J, dtype=float)[None], np.asarray(rw, dtype=float)[None], sigma_known)


def quantile(dof: int, sigma_known: bool) -> float | None:
    if sigma_known:
        return norm_ppf(0.975)
    if dof <= 0:
        return None
    return t_ppf(0.975, float(dof))


def identified_columns(null: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Which free parameters are identifiable: the library's one rule.

    Parameters
    ----------
    null : ndarray, shape (p, k)
        Null-space basis of the column-scaled Jacobian (scaled coordinates; ``k`` may be 0).
    usable : ndarray of bool, shape (p,)
        Whether each column is usable (finite, non-zero norm).

    Returns
    -------
    ndarray of bool
        A parameter's component in the null space below :data:`NULL_TOL`, on a usable column.
    """
    comp = np.sqrt((null**2).sum(axis=1)) if null.shape[1] else np.zeros(null.shape[0])
    return (comp < NULL_TOL) & usable


def estimable(g_scaled: np.ndarray, null: np.ndarray) -> bool:
    """Whether a linear functional with gradient ``g_scaled`` (scaled coordinates) is estimable.

    Its gradient's part in the null space, relative to its norm, below :data:`NULL_TOL` (a zero
    gradient is estimable: the functional does not depend on the free parameters).
    """
    nrm = float(np.linalg.norm(g_scaled))
    return nrm == 0 or null.shape[1] == 0 or float(np.linalg.norm(g_scaled @ null)) / nrm < NULL_TOL
