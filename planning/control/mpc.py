"""The receding-horizon slip/torque problem: built once per vehicle and horizon, soil and state as parameters.

Decision: the slips ``i_0 .. i_{N-1}`` held over the horizon's intervals of ``h`` seconds. The hull
follows Eq. 1 with the quasi-static sprocket (the slip settles in milliseconds, far below ``h``)::

    v_{k+1} = v_k + h (F(i_k) - R - R_s i_k) / m,   F(i) = F_max g(i l / K)  (Eq. 2, soilmodel's slip factor)
    M_k = r F(i_k),   w_k = v_k / (r (1 - i_k))

Limits: ``0 <= i_k <= i_max``, ``M_k <= M_max``, ``M_k w_k <= P_max``. Objective: the squared
speed error to the target (relative), the sprocket energy (relative to the target's kinetic
energy), and the slip's changes. SQP (CasADi's ``sqpmethod``, exact Hessian convexified by eigenvalue
clipping, QPs by qpOASES), quiet, warm-started from the previous solution (its plan shifted by one
interval, and its multipliers). The exact Hessian is indefinite (the energy term and the concave slip
factor); with QRQP on the unconvexified QPs about 2 % of the solves took 30-500 ms (QRQP grinding on an
indefinite QP, then ``Search_Direction_Becomes_Too_Small``), which set the step's p99. ``qp="qrqp"``
keeps that solver for comparison (benchmarks/bench_control.py ``--mpc-qp qrqp``). When SQP fails,
IPOPT from the same warm start, bounded to 15 iterations (no CPU-time cap: that made runs
load-dependent); when that fails too, the previous plan shifted is returned (counted in ``failures``,
``failed_last``) and the controller drives by the slip controller's rule until the next solve succeeds.
``R_s = N mu_s`` is the slip sinkage's resistance per unit slip (soilmodel's ``slip_sinkage`` effect).
Parameters ``[v0, F_max, K, R, R_s, v_ref, i_prev, i_max, M_max, P_max]``.
"""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel import Vehicle
from ...soilmodel.traction import slip_factor

__all__ = ["MPC_PARAMS", "MPC_METHODS", "mpc_solver", "MpcProblem"]

MPC_PARAMS = ("v0", "F_max", "K", "R", "R_s", "v_ref", "i_prev", "i_max", "M_max", "P_max")
#: The SQP's QP setups: ``"qpoases"`` (default; convexified Hessian) and ``"qrqp"`` (the exact Hessian, last round's).
MPC_METHODS = ("qpoases", "qrqp")


@contextmanager
def _stdout_to_devnull():
    """Silence the C-level stdout while a solver is built (qpOASES prints its licence banner on
    construction, whatever its ``printLevel``; it would land in ``--json`` output)."""
    sys.stdout.flush()
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # no real stdout (captured): nothing C-level to guard
        yield
        return
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


@lru_cache(maxsize=16)
def mpc_solver(
    vehicle: Vehicle, horizon: int, h: float, w_energy: float, w_smooth: float, method: str = "sqp"
) -> ca.Function:
    """The solver of the horizon's problem (module docstring), built once per arguments: ``"qpoases"`` (SQP,
    convexified Hessian, qpOASES), ``"qrqp"`` (SQP, exact Hessian, QRQP) or ``"ipopt"`` (the fall-back)."""
    i = ca.SX.sym("i", horizon)
    p = ca.SX.sym("p", len(MPC_PARAMS))
    v0, Fmax, K, R, Rs, vref, iprev, _imax, Mmax, Pmax = (p[j] for j in range(len(MPC_PARAMS)))
    m, r, l = vehicle.mass, vehicle.sprocket_radius, vehicle.track_length
    v = v0
    J = 0
    g = []
    E_ref = 0.5 * m * ca.fmax(vref, 0.1) ** 2
    i_last = iprev
    for k in range(horizon):
        F = Fmax * slip_factor(i[k], l, K)
        w = ca.fmax(v, 0.0) / (r * (1 - i[k]))
        g += [r * F / Mmax, r * F * w / Pmax]
        J += w_energy * r * F * w * h / E_ref + w_smooth * ((i[k] - i_last) / 0.01) ** 2
        v = v + h * (F - R - Rs * i[k]) / m
        J += ((v - vref) / ca.fmax(vref, 0.1)) ** 2
        i_last = i[k]
    nlp = {"x": i, "p": p, "f": J, "g": ca.vertcat(*g)}
    if method in MPC_METHODS:
        sqp: dict[str, Any] = {
            "print_header": False,
            "print_iteration": False,
            "print_status": False,
            "print_time": False,
            "max_iter": 30,
            "error_on_fail": False,
        }
        if method == "qrqp":  # exact (indefinite) Hessian: QRQP grinds on some QPs (module docstring)
            qp = {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False}
            return ca.nlpsol("slip_mpc_qrqp", "sqpmethod", nlp, {**sqp, "qpsol": "qrqp", "qpsol_options": qp})
        opts_q = {
            **sqp,
            "qpsol": "qpoases",
            "qpsol_options": {"printLevel": "none", "error_on_fail": False},
            "convexify_strategy": "eigen-clip",  # the exact Hessian with its negative eigenvalues clipped
            "convexify_margin": 1e-6,
        }
        with _stdout_to_devnull():
            return ca.nlpsol("slip_mpc_sqp", "sqpmethod", nlp, opts_q)
    opts: dict[str, Any] = {
        "ipopt.print_level": 0,
        "print_time": False,
        "ipopt.sb": "yes",
        # an iteration cap, not a time cap: a CPU-time limit made the closed loop depend on the machine's load
        "ipopt.max_iter": 15,
        "ipopt.tol": 1e-6,
        "ipopt.warm_start_init_point": "yes",
        "ipopt.mu_init": 1e-3,
    }
    return ca.nlpsol("slip_mpc", "ipopt", nlp, opts)


class MpcProblem:
    """One horizon problem, re-solved warm (module docstring); ``solve`` gives the slip plan."""

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        horizon: int = 10,
        h: float = 0.2,
        w_energy: float = 0.05,
        w_smooth: float = 0.01,
        qp: str = "qpoases",
    ) -> None:
        if qp not in MPC_METHODS:
            raise ValueError(f"unknown MPC QP setup {qp!r}; expected one of {MPC_METHODS}")
        self.vehicle, self.horizon, self.h = vehicle, horizon, h
        self._solver = mpc_solver(vehicle, horizon, float(h), float(w_energy), float(w_smooth), qp)
        self._fallback = mpc_solver(vehicle, horizon, float(h), float(w_energy), float(w_smooth), "ipopt")
        self._x = np.full(horizon, 0.02)
        self._lam_x = np.zeros(horizon)
        self._lam_g = np.zeros(2 * horizon)
        self.last_status = "not solved"
        self.last_iterations = 0
        self.failures = 0
        self.failed_last = False  # whether the last solve failed (the plan returned is the previous one shifted)
        self.fallbacks = 0  # SQP failures re-solved by IPOPT
        self.fallback_reasons: dict[str, int] = {}
        self.iterations: list[int] = []  # iterations of each solve's last solver
        self.solver_cpu_s: list[tuple[bool, str, float]] = []  # (IPOPT?, status, CPU s) of every solver call
        # the first IPOPT call loads its plugin (~0.3 s): done here, not in the first fall-back of a run
        self._fallback(x0=self._x, p=np.ones(len(MPC_PARAMS)), lbx=0.0, ubx=0.5, lbg=-np.inf, ubg=1.0)

    def solve(
        self,
        v0: float,
        F_max: float,
        K: float,
        R: float,
        R_s: float,
        v_ref: float,
        i_prev: float,
        i_max: float,
        M_max: float,
        P_max: float,
    ) -> np.ndarray:
        """The slips of the horizon (the first is applied): SQP, IPOPT when SQP fails, else the previous plan
        shifted (counted in ``failures``)."""
        p = np.array([v0, F_max, K, R, R_s, v_ref, i_prev, i_max, M_max, P_max], dtype=float)
        x0 = np.clip(np.append(self._x[1:], self._x[-1]), 0.0, i_max)
        for solver in (self._solver, self._fallback):
            if solver is self._fallback:
                self.fallbacks += 1
                self.fallback_reasons[self.last_status] = self.fallback_reasons.get(self.last_status, 0) + 1
            c0 = time.process_time()
            sol = solver(x0=x0, p=p, lbx=0.0, ubx=i_max, lbg=-np.inf, ubg=1.0, lam_x0=self._lam_x, lam_g0=self._lam_g)
            st = _stats(solver)
            self.solver_cpu_s.append(
                (solver is self._fallback, str(st.get("return_status", "")), time.process_time() - c0)
            )
            self.last_status = str(st.get("return_status", ""))
            x = np.asarray(sol["x"], dtype=float).ravel()
            ok = bool(st.get("success", False))
            if ok and np.all(np.isfinite(x)):
                break
        self.last_status = str(st.get("return_status", ""))
        self.last_iterations = int(st.get("iter_count", 0))
        self.iterations.append(self.last_iterations)
        self.failed_last = not ok or not np.all(np.isfinite(x))
        if self.failed_last:
            self.failures += 1
            self._x = x0
            return x0
        self._x = x
        self._lam_x = np.asarray(sol["lam_x"], dtype=float).ravel()
        self._lam_g = np.asarray(sol["lam_g"], dtype=float).ravel()
        return x


def _stats(solver: ca.Function) -> dict:
    """The solver's stats; a failure when CasADi cannot give them (its ``stats`` raised "construction from
    null" once for an SQP whose QP failed)."""
    try:
        return dict(solver.stats())
    except RuntimeError:
        return {"return_status": "no stats", "success": False, "iter_count": 0}
