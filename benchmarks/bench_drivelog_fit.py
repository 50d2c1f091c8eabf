#!/usr/bin/env python
"""A joint drive-log fit (soil + one effect + a latent slip per sample) against ``scipy.optimize.least_squares``.

Run:  python benchmarks/bench_drivelog_fit.py [--vehicle heavy] [--seconds 60] [--effect grade] [--repeats 3]
                                            [--max-nfev 1000]

The problem is the one ``fit(log, vehicle, effects=[...])`` solves for every candidate of a drive-log
diagnosis: three whitened residual channels per sample (speed, sprocket thrust, hull balance),
the thrust limit, K and the effect's parameters, and one latent slip per sample. soiltrack: the
default path (a few profiled Levenberg-Marquardt steps, then IPOPT with the exact Hessian). scipy
(extra ``bench``): ``least_squares(method="trf")`` on the SAME residuals - the library's CasADi
residual function, mapped over the samples, is the user's function, so no physics is copied -
with the same bounds, scaled variables and start (the nominal start, the effect off, the latent
slips at their per-sample optimum there), tolerances 1e-12, ``--max-nfev`` evaluations at most
(status 0 says the budget ran out), and

* ``2-point``: finite differences with the Jacobian's sparsity given (what a user would script);
* ``analytic``: the exact sparse Jacobian from CasADi's per-sample sensitivities (scipy's best case).

Times are medians over ``--repeats`` calls after a warm-up (solvers built, C kernels loaded); the
final costs and parameters are compared. Prints the load average before and after.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from soiltrack.identify import fit  # noqa: E402
from soiltrack.identify.drivelog.joint import (
    best_slips,
    effect_layout,
    joint_data,
    residual_function,  # noqa: E402
    sensitivity_function,
)
from soiltrack.identify.drivelog.fit import _start_points  # noqa: E402
from soiltrack.identify.drivelog.nlp import fmax_bounds, g_inverse  # noqa: E402
from soiltrack.identify.drivelog.prepare import SLIP_BOUNDS, prepare_drive_log  # noqa: E402
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate  # noqa: E402
from soiltrack.soilmodel.effects import effect_structure, parse_effects  # noqa: E402
from soiltrack.soilmodel.soil import PRACTICAL_BOUNDS  # noqa: E402


def scipy_problem(log, vehicle, effect):
    """Residuals, Jacobians, bounds and start of the joint problem in scaled variables."""
    from scipy import sparse

    prep = prepare_drive_log(log, vehicle)
    jd = joint_data(log, vehicle, prep)
    st = effect_structure(parse_effects([effect]), vehicle)
    res_fn, labels = residual_function(vehicle, st)
    sens = sensitivity_function(vehicle, st)
    n = prep.n_used
    elo, ehi, esc = effect_layout(list(labels), vehicle)
    Fb = fmax_bounds(PRACTICAL_BOUNDS, vehicle, "full")
    Kb = tuple(PRACTICAL_BOUNDS.shear_modulus)
    F_ref, K_ref = 0.5 * (Fb[0] + Fb[1]), math.sqrt(Kb[0] * Kb[1])
    i_ref = K_ref / vehicle.track_length
    scale = np.concatenate([[F_ref, K_ref], esc])
    p = scale.size
    ((F0, K0),) = _start_points(prep, vehicle, "full", None, Fb, Kb, K_ref, multistart=False)[0]  # the fit's start
    th0 = np.concatenate([[F0, K0], np.zeros(len(labels))])
    lo_s, hi_s = SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3
    y = np.clip(np.abs(prep.thrust) / F0, 0.0, 0.98)
    s_inv = np.clip(np.sign(prep.thrust) * g_inverse(y) * K0 / vehicle.track_length, lo_s, hi_s)
    s0 = best_slips(vehicle, st, th0, jd.D, [s_inv, np.clip(prep.slip_measured, lo_s, hi_s)])
    x0 = np.concatenate([th0 / scale, s0 / i_ref])
    lb = np.concatenate(
        [
            [Fb[0] / F_ref, Kb[0] / K_ref],
            np.where(np.isfinite(elo), elo / esc, -np.inf),
            np.full(n, SLIP_BOUNDS[0] / i_ref),
        ]
    )
    ub = np.concatenate(
        [
            [Fb[1] / F_ref, Kb[1] / K_ref],
            np.where(np.isfinite(ehi), ehi / esc, np.inf),
            np.full(n, SLIP_BOUNDS[1] / i_ref),
        ]
    )
    x0 = np.clip(x0, lb + 1e-9, ub - 1e-9)
    rmap, smap = res_fn.map(n), sens.map(n)

    def unpack(x):
        return np.repeat((x[:p] * scale).reshape(-1, 1), n, axis=1), (x[p:] * i_ref).reshape(1, -1)

    def residuals(x):
        th, s = unpack(x)
        return np.asarray(rmap(th, s, jd.D)[0], dtype=float).T.ravel()  # sample by sample, 3 each

    rows = np.repeat(np.arange(3 * n), p + 1)
    cols = np.concatenate([np.concatenate([np.arange(p), [p + k]]) for k in range(n) for _ in range(3)])
    pattern = sparse.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(3 * n, p + n))

    def jacobian(x):
        th, s = unpack(x)
        _, Jt, gi = (np.asarray(o, dtype=float) for o in smap(th, s, jd.D))
        Jt = Jt.reshape(3, n, p).transpose(1, 0, 2) * scale  # (n, 3, p) in scaled variables
        gi = gi.T * i_ref  # (n, 3)
        vals = np.concatenate([Jt, gi[:, :, None]], axis=2).ravel()
        return sparse.csr_matrix((vals, (rows, cols)), shape=(3 * n, p + n))

    return dict(
        residuals=residuals, jacobian=jacobian, pattern=pattern, x0=x0, bounds=(lb, ub), scale=scale, labels=labels, n=n
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicle", default="heavy")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--effect", default="grade")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--max-nfev", type=int, default=1000, help="scipy's evaluation budget (status 0: spent)")
    a = ap.parse_args(argv)
    try:
        from scipy.optimize import least_squares
    except ImportError:
        print("scipy is needed for the comparison: pip install -e '.[bench]'", file=sys.stderr)
        return 2
    print("load average before:", os.getloadavg())
    v = VEHICLES[a.vehicle]
    log = simulate(
        v,
        TERRAINS["lete_sand"],
        kind="drive",
        effects={a.effect: 0.03} if a.effect == "grade" else None,
        seed=1,
        duration_s=a.seconds,
    )
    prob = scipy_problem(log, v, a.effect)
    print(
        f"{a.vehicle} vehicle, {log.n_samples} samples ({prob['n']} used), effect {a.effect}: "
        f"{len(prob['x0'])} unknowns, {3 * prob['n']} residuals"
    )

    def run_soiltrack():
        r = fit(log, v, effects=[a.effect], torque_hold="zoh")  # the hold the scipy problem uses
        return r, float(r.cost), r.extra["joint_parameters"]

    def run_scipy(kind):
        kw = dict(jac=prob["jacobian"]) if kind == "analytic" else dict(jac="2-point", jac_sparsity=prob["pattern"])
        r = least_squares(
            prob["residuals"],
            prob["x0"],
            bounds=prob["bounds"],
            method="trf",
            x_scale="jac",
            ftol=1e-12,
            xtol=1e-12,
            gtol=1e-12,
            max_nfev=a.max_nfev,
            **kw,
        )
        th = r.x[: len(prob["scale"])] * prob["scale"]
        return (
            r,
            float(r.cost),
            {"max_thrust_N": th[0], "shear_modulus_m": th[1], "effects": dict(zip(prob["labels"], th[2:].tolist()))},
        )

    runs = {
        "soiltrack fit (profiled start + IPOPT)": run_soiltrack,
        "scipy least_squares trf, 2-point with sparsity": lambda: run_scipy("2-point"),
        "scipy least_squares trf, analytic sparse Jacobian": lambda: run_scipy("analytic"),
    }
    times = {k: [] for k in runs}
    out = {}
    for k, f in runs.items():  # warm-up: solvers built, kernels loaded
        f()
    for _ in range(a.repeats):  # round-robin, so that load changes hit all alike
        for k, f in runs.items():
            t = time.perf_counter()
            out[k] = f()
            times[k].append(time.perf_counter() - t)
    ref = out["soiltrack fit (profiled start + IPOPT)"]
    for k in runs:
        r, cost, jp = out[k]
        status = f"{r.status}" if hasattr(r, "iterations") else f"status {r.status}, {r.nfev} evaluations"
        eff = ", ".join(f"{lab} = {val:.5g}" for lab, val in jp["effects"].items())
        print(
            f"{k:52s} median {np.median(times[k]):7.2f} s   cost {cost:.10g} "
            f"(rel. diff {(cost - ref[1]) / ref[1]:+.1e})   K = {1000 * jp['shear_modulus_m']:.4g} mm, {eff}; {status}"
        )
    print("load average after:", os.getloadavg())
    return 0


if __name__ == "__main__":
    sys.exit(main())
