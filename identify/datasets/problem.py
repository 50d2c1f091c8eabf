"""The joint problem of several data sets on one soil: blocks, the cached IPOPT solver.

Each data set is a block with its own concentrated Gaussian log-likelihood, one term
``n_k / 2 log(SSR_k + n_k s_floor,k^2)`` per channel (each channel its own unknown noise level),
the form of the wheel's own fit (:func:`soiltrack.identify.wheel.problem.wheel_block`, built
there and reused here). The objective is the sum of the blocks, so at one data set it is that
data set's own fit, and twice a block's rise from its own optimum to the joint one is its share of
the likelihood-ratio statistic. Blocks:

- ``wheel``: a rigid wheel's sweep (drawbar pull, sinkage and torque where measured), all six soil
  parameters and its own slip-sinkage coefficient (a gear-specific parameter);
- ``shear``: a bevameter shear test (stress against displacement, Janosi-Hanamoto): c, phi, K;
- ``annulus``: a shear annulus (torque against rotation, integrated across the ring): c, phi, K;
- ``plate``: a plate sinkage test (Bekker pressure): k_c, k_phi, n;
- ``track``: a tracked vehicle's slip sweep (tractive force or drawbar pull against slip, the
  sweep fit's own observation Function, :func:`soiltrack.identify.sweep.model.observation_function`,
  without effects - a joint fit refuses effects with a track data set): c, phi, K. Each row's residual
  is divided by its weight ``sigma_k`` from the single fit's own rule (the sweep problem's
  :attr:`~soiltrack.identify.sweep.problem.SlipProblem.sigma`: the per-row std column as relative
  weights, else ones), so the block is ``n/2 log(sum (r_k / sigma_k)^2 + n floor^2)``, the concentrated
  likelihood of noise ``s sigma_k`` with ``s`` unknown: alone, the single fit's weighted least squares;
- ``drivelog``: a drive log, entered as its own fit's estimate of ``(F_max, K)`` with their
  covariance (the log's likelihood to second order at its optimum; the latent-slip fit is
  :func:`soiltrack.identify.drivelog.fit.fit_drive_log`'s): ``F_max = A c + W tan(phi)``
  (:func:`soiltrack.soilmodel.traction.max_thrust_expr`) and K. Its block is
  ``1/2 |L (g(theta) - g_hat)|^2`` with ``L^T L`` the inverse covariance: zero at the log's own
  fit, so twice its rise is its Mahalanobis distance, the log's share of the statistic.

Variables: the free shared soil parameters, then each wheel block's free gear-specific
parameters, scaled by :data:`~soiltrack.identify.wheel.problem.PARAMETER_SCALES`. NLP parameters:
the held values (6 shared, then one per block), then every block's data. The solver is built once
per (block specs, free mask) and cached; the data enter as parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel.bevameter import annulus_torque_expr, plate_pressure_expr, shear_stress_expr
from ...soilmodel.rigid_wheel import RigidWheel
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.traction import max_thrust_expr
from ...soilmodel.vehicle import Vehicle
from ...soilmodel.wheel import WheelSettings
from ..sweep.model import observation_function
from ..wheel.problem import (
    NOISE_FLOOR_REL,
    PARAMETER_SCALES,
    WHEEL_IPOPT_OPTIONS,
    WHEEL_PARAMETERS,
    WheelBounds,
    wheel_block,
)

__all__ = [
    "SHARED",
    "SPECIFIC",
    "BlockSpec",
    "block_touches",
    "joint_solver",
    "N_SHARED",
    "N_SPECIFIC",
    "GROUSER_SCALE",
    "SUMMARY_CHANNEL",
    "TRACK_KINDS",
]

#: The soil's parameters, shared by every data set (SI names of the wheel fit).
SHARED = WHEEL_PARAMETERS[:6]
N_SHARED = len(SHARED)
#: A wheel's gear-specific parameters (one each per data set): the slip-sinkage coefficient and the
#: grouser height (m; held at the wheel's unless freed).
SPECIFIC = (WHEEL_PARAMETERS[6], "grouser_height")
N_SPECIFIC = len(SPECIFIC)
#: Scale of the grouser height inside the solver, m (solved for in centimetres).
GROUSER_SCALE = 1e-2
#: Upper bound of a fitted grouser height, as a fraction of the wheel's radius.
GROUSER_MAX_REL = 0.5
#: The channel of a drive-log block: its own fit's (F_max, K) whitened by their covariance (known scale 1).
SUMMARY_CHANNEL = "drive_log_max_thrust_and_shear_modulus"
#: The block kinds of a tracked vehicle (running gear a :class:`Vehicle`).
TRACK_KINDS = ("track", "drivelog")
#: Length of a drive-log block's data vector: g_hat (2), the whitening matrix L (4, row-major), W, A.
_SUMMARY_P = 8


@dataclass(frozen=True)
class BlockSpec:
    """What shapes one data set's block (hashable: the solver's cache key).

    ``kind`` one of ``wheel``, ``shear``, ``annulus``, ``plate``, ``track``, ``drivelog``; ``n`` its rows;
    for a wheel its :class:`RigidWheel`, the model settings, whether sinkage and torque are measured and
    whether its slip-sinkage coefficient is free; for a track sweep or a drive log its :class:`Vehicle`
    (and for a sweep the measured quantity, ``tractive_force`` or ``drawbar_pull``, and ``weighted``: whether
    its rows carry the per-row std column's weights; its channel is then the residual in units of each row's
    std, ``{measured}_N_per_std``).
    """

    kind: str
    n: int
    wheel: RigidWheel | None = None
    settings: WheelSettings | None = None
    sinkage: bool = False
    torque: bool = False
    specific_free: bool = False
    grouser_free: bool = False
    vehicle: Vehicle | None = None
    measured: str = "tractive_force"
    weighted: bool = False

    @property
    def p_size(self) -> int:
        """Length of the block's data vector."""
        if self.kind == "wheel":
            return (6 if self.torque else 4) * self.n
        if self.kind == "drivelog":
            return _SUMMARY_P
        return {"shear": 3, "annulus": 5, "plate": 3, "track": 4}[self.kind] * self.n + (
            1 if self.kind == "plate" else 0
        )

    @property
    def channels(self) -> tuple[str, ...]:
        """Names of the block's channels, in the order of its residuals."""
        if self.kind == "wheel":
            return (
                ("drawbar_pull_N",)
                + (("sinkage_m",) if self.sinkage else ())
                + (("wheel_torque_Nm",) if self.torque else ())
            )
        return {
            "shear": ("shear_stress_Pa",),
            "annulus": ("torque_per_ring_Pa",),
            "plate": ("pressure_Pa",),
            "track": (f"{self.measured}_N_per_std" if self.weighted else f"{self.measured}_N",),
            "drivelog": (SUMMARY_CHANNEL,),
        }[self.kind]


def box8(spec: BlockSpec, bounds: WheelBounds) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower, upper bounds and solver scales of a block's 8-vector (7 wheel parameters, grouser height)."""
    r = spec.wheel.radius if spec.wheel is not None else 1.0
    lo = np.append(np.array(bounds.lower, dtype=float), 0.0)
    hi = np.append(np.array(bounds.upper, dtype=float), GROUSER_MAX_REL * r)
    return lo, hi, np.append(PARAMETER_SCALES, GROUSER_SCALE)


def block_touches(spec: BlockSpec) -> tuple[bool, ...]:
    """Which of the six shared soil parameters the block's data depend on."""
    if spec.kind == "wheel":
        return (True,) * N_SHARED
    if spec.kind == "plate":
        return (False, False, False, True, True, True)
    return (True, True, True, False, False, False)  # shear, annulus, track sweep, drive log


def _floor_term(r, floor, n: int):
    return n / 2 * ca.log(ca.sumsqr(r) + n * floor**2)


def _block(spec: BlockSpec, theta, p, h=None) -> tuple[Any, list[tuple[Any, Any]]]:
    """``(f, [(residual, floor), ...])`` of one block (theta: 7 SI parameters; h the grouser height if freed)."""
    n = spec.n
    if spec.kind in TRACK_KINDS:
        return _track_block(spec, theta, p)
    cols = [p[q * n : (q + 1) * n] for q in range(spec.p_size // n)]
    if spec.kind == "wheel":
        assert spec.wheel is not None and spec.settings is not None
        f, (r_dp, r_w, r_t) = wheel_block(
            spec.wheel, spec.settings, n, spec.sinkage, spec.torque, theta, p, grouser_height=h
        )
        W = cols[2]
        floor = NOISE_FLOOR_REL * ca.sum1(W) / n
        out = [(r_dp, floor)]
        if spec.sinkage:
            from ..wheel.problem import SINKAGE_FLOOR_M

            out.append((r_w, ca.DM(SINKAGE_FLOOR_M)))
        if spec.torque:
            out.append((r_t, floor * spec.wheel.radius))
        return f, out
    c, phi, K, k_c, k_phi, n_b = (theta[q] for q in range(N_SHARED))
    if spec.kind == "shear":
        sigma, j, tau = cols
        r = shear_stress_expr(j, sigma, c, phi, K) - tau
        floor = NOISE_FLOOR_REL * ca.mmax(ca.fabs(tau))
    elif spec.kind == "annulus":
        sigma, rot, tq, r_i, r_o = cols
        ring = 2 * np.pi * (r_o**3 - r_i**3) / 3
        r = annulus_torque_expr(rot, sigma, c, phi, K, r_i, r_o) / ring - tq / ring
        floor = NOISE_FLOOR_REL * ca.mmax(ca.fabs(tq / ring))
    else:
        b, z, pr = cols
        z_ref = p[3 * n]
        r = plate_pressure_expr(z, b, k_c, k_phi, n_b, z_ref) - pr
        floor = NOISE_FLOOR_REL * ca.mmax(ca.fabs(pr))
    return _floor_term(r, floor, n), [(r, floor)]


def _track_block(spec: BlockSpec, theta, p) -> tuple[Any, list[tuple[Any, Any]]]:
    """A track sweep's concentrated log-likelihood, or a drive log's quadratic summary (see the module)."""
    assert spec.vehicle is not None
    c, phi, K = theta[0], theta[1], theta[2]
    if spec.kind == "drivelog":
        g_hat, L, W, A = p[0:2], ca.reshape(p[2:6], 2, 2).T, p[6], p[7]
        r = ca.mtimes(L, ca.vertcat(max_thrust_expr(c, phi, W, A, "full"), K) - g_hat)
        return 0.5 * ca.sumsqr(r), [(r, ca.DM(0.0))]
    n = spec.n
    i, W, y, sigma = p[0:n], p[n : 2 * n], p[2 * n : 3 * n], p[3 * n : 4 * n]
    obs = observation_function(spec.vehicle, None, "full", spec.measured).map(n)
    y_model = obs(i.T, W.T, ca.repmat(ca.vertcat(c, phi, K), 1, n))[0].T
    r = (y_model - y) / sigma  # the single fit's weighted residual (sigma all ones without a std column)
    floor = NOISE_FLOOR_REL * ca.mmax(ca.fabs(y / sigma))
    return _floor_term(r, floor, n), [(r, floor)]


def _theta_blocks(x, p, specs: tuple[BlockSpec, ...], shared_free: tuple[bool, ...]):
    """The 7-vector and the grouser height of every block from the variables and the held values (two per
    block: s, h), and the SI variables' scales."""
    parts, scales, q = [], [], 0
    for k in range(N_SHARED):
        if shared_free[k]:
            parts.append(x[q] * PARAMETER_SCALES[k])
            scales.append(PARAMETER_SCALES[k])
            q += 1
        else:
            parts.append(p[k])
    thetas, hs = [], []
    for d, spec in enumerate(specs):
        if spec.specific_free:
            s = x[q] * PARAMETER_SCALES[N_SHARED]
            scales.append(PARAMETER_SCALES[N_SHARED])
            q += 1
        else:
            s = p[N_SHARED + N_SPECIFIC * d]
        if spec.grouser_free:
            hs.append(x[q] * GROUSER_SCALE)
            scales.append(GROUSER_SCALE)
            q += 1
        else:
            hs.append(p[N_SHARED + N_SPECIFIC * d + 1])
        thetas.append(ca.vertcat(*parts, s))
    return thetas, hs, np.array(scales)


@locked_cache(maxsize=32)
def joint_solver(specs: tuple[BlockSpec, ...], shared_free: tuple[bool, ...]) -> tuple[ca.Function, ca.Function]:
    """The cached IPOPT solver of the joint problem and its evaluation Function.

    ``eval(x_si, p) -> [theta (6 + 2 per block: s, h), f per block, then per block and channel: residual,
    Jacobian w.r.t. the SI variables, floor]``.
    """
    nf = sum(shared_free) + sum(s.specific_free + s.grouser_free for s in specs)
    x = ca.MX.sym("x", nf)
    off = N_SHARED + N_SPECIFIC * len(specs)
    p = ca.MX.sym("p", off + sum(s.p_size for s in specs))
    thetas, hs, scales = _theta_blocks(x, p, specs, shared_free)
    fs, chans = [], []
    for spec, th, h in zip(specs, thetas, hs):
        f, ch = _block(spec, th, p[off : off + spec.p_size], h if spec.grouser_free else None)
        off += spec.p_size
        fs.append(f)
        chans.append(ch)
    solver = ca.nlpsol("joint_fit", "ipopt", {"x": x, "p": p, "f": ca.sum1(ca.vertcat(*fs))}, dict(WHEEL_IPOPT_OPTIONS))
    xs = ca.MX.sym("xs", nf)
    xsc = xs / ca.DM(scales) if nf else xs
    sub = lambda e: ca.substitute(e, x, xsc)  # noqa: E731 - the SI variables in place of the scaled ones
    theta_all = ca.vertcat(thetas[0][:N_SHARED], *[ca.vertcat(th[N_SHARED], h) for th, h in zip(thetas, hs)])
    outs = [sub(theta_all), sub(ca.vertcat(*fs))]
    for ch in chans:
        for r, floor in ch:
            rs = sub(r)
            outs += [rs, ca.jacobian(rs, xs), sub(floor)]
    return solver, ca.Function("joint_eval", [xs, p], outs)
