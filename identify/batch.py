"""Many fits at once: ``fit_many`` and its vectorised engine.

Same-size tractive force-slip datasets fitted with ``method="ipopt"`` are solved TOGETHER by
a vectorised, bounded (projected) Levenberg-Marquardt iteration in numpy: every array has a
leading axis over the datasets, so one iteration costs a few numpy calls for all of them.
It solves exactly the same bounded weighted least-squares problem as the IPOPT path, from
the same variable-projection start, and stops on the same first-order (KKT) conditions;
any dataset it does not certify is re-solved with the cached IPOPT solver (said in its
message). The results are labelled ``method="ipopt"`` (the estimator: bounded least
squares within the practical ranges) with ``extra["engine"]`` naming what solved them
(``"batch-lm"`` or ``"ipopt"``). The start grid has 13 K values here (25 in ``fit``): the
local iteration converges to the same optimum from either, and the coarser grid halves the
start cost. Other methods, drive logs and mixed sizes go one by one
through :func:`~soiltrack.identify.fit` (the solvers are cached, so nothing is rebuilt). With
``engine="auto"`` (default) same-size groups smaller than ``SMALL_GROUP`` datasets - e.g.
``fit_many([data])`` - go one by one through the compiled single-fit engine
(:mod:`soiltrack.identify.compiled_lm`, ``extra["engine"] == "compiled-lm"``), whose fixed
cost per fit is far below the vectorised engine's for a handful of datasets.

Parallelism: pass any :class:`concurrent.futures.Executor`; work is submitted in chunks
(``chunk_size`` datasets each). For Dask, ``client.get_executor()`` of a
``dask.distributed.Client`` is such an executor (dask is not required).
"""
from __future__ import annotations

import sys
import time
from concurrent.futures import Executor
from typing import Iterable, Sequence

import numpy as np

from ..soilmodel.data import SlipData
from ..soilmodel.errors import DataError
from ..soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ..soilmodel.vehicle import Vehicle
from .ipopt_fit import solve_ipopt
from .npmodel import thrust_and_jacobian
from .problem import (SCALE, FitFailed, check_common, heteroscedasticity, heteroscedasticity_warning,
                      make_problem, relative_sigma, ridge_centre)
from .result import FitResult, build_results_batch
from .start import grid_start

__all__ = ["fit_many", "solve_batch", "SMALL_GROUP"]

#: ``fit_many(engine="auto")``: same-size groups smaller than this use the compiled single-fit engine.
SMALL_GROUP = 8


def solve_batch(slip, force, load, sigma, l: float, b: float, model: str, bounds: SoilBounds,
                theta0: np.ndarray | None = None, max_iter: int = 200, n_grid: int = 25, lam0: float = 1e-3) -> dict:
    """Vectorised projected Levenberg-Marquardt for N same-size problems (arrays (N, n)).

    Returns ``theta`` (N, 3), ``converged`` (N,), ``iterations`` (N,).
    """
    slip, force, load, sigma = (np.asarray(a, float) for a in (slip, force, load, sigma))
    N = slip.shape[0]
    free = [0, 1, 2] if model == "full" else [1, 2]
    p = len(free)
    sc = SCALE[free]
    lo = bounds.lower[free] / sc
    hi = bounds.upper[free] / sc
    if theta0 is None:
        theta0 = grid_start(slip, force, load, sigma, l, b, model, bounds, n_grid=n_grid)
    theta = np.array(theta0, float)
    if model == "cohesion-free":
        theta[:, 0] = 0.0
    z = np.clip(theta[:, free] / sc, lo, hi)
    lam = np.full(N, lam0)
    iters = np.zeros(N, dtype=int)
    conv = np.zeros(N, dtype=bool)
    live = np.arange(N)
    eps_b = 1e-12 * (hi - lo)

    def evaluate(zz, idx):
        th = np.zeros((idx.size, 3))
        th[:, free] = zz * sc
        F, J = thrust_and_jacobian(th, slip[idx], load[idx], l, b, model)
        rw = (F - force[idx]) / sigma[idx]
        Js = J[:, :, free] * sc / sigma[idx][:, :, None]
        return rw, Js

    rw, Js = evaluate(z, live)
    cost = 0.5 * np.einsum("ki,ki->k", rw, rw)
    eye = np.eye(p)
    for _ in range(max_iter):
        if live.size == 0:
            break
        g = np.einsum("kij,ki->kj", Js, rw)
        H = np.einsum("kij,kil->kjl", Js, Js)
        zl = z[live]
        active = ((zl <= lo + eps_b) & (g > 0)) | ((zl >= hi - eps_b) & (g < 0))
        # first-order optimality (projected gradient) relative to the problem's scale
        gp = np.where(active, 0.0, g)
        scale_g = np.sqrt(np.einsum("kjj->k", H) * np.maximum(2 * cost[live], 1e-300))
        kkt = np.linalg.norm(gp, axis=1) <= 1e-9 * scale_g + 1e-300
        dH = np.einsum("kjj->kj", H)
        Hd = H + lam[live][:, None, None] * (dH[:, :, None] * eye) + 1e-30 * eye
        free_mask = ~active
        Hd = np.where(free_mask[:, :, None] & free_mask[:, None, :], Hd, eye)
        rhs = np.where(free_mask, -g, 0.0)
        try:
            step = np.linalg.solve(Hd, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = np.einsum("kjl,kl->kj", np.linalg.pinv(Hd), rhs)
        znew = np.clip(zl + step, lo, hi)
        rw_n, Js_n = evaluate(znew, live)
        cost_n = 0.5 * np.einsum("ki,ki->k", rw_n, rw_n)
        acc = np.isfinite(cost_n) & (cost_n <= cost[live])
        rel = np.where(acc, (cost[live] - cost_n) / np.maximum(cost[live], 1e-300), np.inf)
        iters[live] += 1
        # update accepted
        z[live[acc]] = znew[acc]
        cost[live[acc]] = cost_n[acc]
        rw = np.where(acc[:, None], rw_n, rw)
        Js = np.where(acc[:, None, None], Js_n, Js)
        lam[live] = np.where(acc, np.maximum(lam[live] / 10, 1e-12), lam[live] * 10)
        stepn = np.linalg.norm(np.where(acc[:, None], znew - zl, 0.0), axis=1)
        done = (kkt) | (acc & (rel <= 1e-15) & (stepn <= 1e-10 * (1 + np.linalg.norm(zl, axis=1)))) | \
               (lam[live] > 1e12)
        # a stop without first-order optimality is not convergence
        conv[live[done]] = kkt[done] | (acc[done] & (rel[done] <= 1e-15))
        keep = ~done
        live = live[keep]
        rw, Js = rw[keep], Js[keep]
    theta = np.zeros((N, 3))
    theta[:, free] = z * sc
    return {"theta": theta, "converged": conv, "iterations": iters}


def _solve_chunk(datasets: Sequence[SlipData], vehicle: Vehicle, model: str, bounds: SoilBounds, sigma,
                 sigma_known, n_grid: int) -> list[FitResult]:
    t0 = time.perf_counter()
    # the SlipData are validated on construction; stack them directly (no per-dataset Python work)
    slip = np.stack([d.slip for d in datasets])
    force = np.stack([d.tractive_force for d in datasets])
    Wv = vehicle.weight
    if all(d.normal_load is None for d in datasets):
        load = np.full(slip.shape, Wv)
    else:
        load = np.stack([d.normal_load if d.normal_load is not None else np.full(d.slip.size, Wv) for d in datasets])
    if sigma is None:
        sig = np.ones_like(slip)
        sk = False if sigma_known is None else bool(sigma_known)
    elif isinstance(sigma, str):
        if sigma != "relative":
            raise DataError(f"sigma must be a number or 'relative', got {sigma!r}")
        sig, sk = relative_sigma(force), False
    else:
        sig = np.full_like(slip, float(sigma))
        sk = True if sigma_known is None else bool(sigma_known)
    l, b = vehicle.track_length, vehicle.track_width
    out = solve_batch(slip, force, load, sig, l, b, model, bounds, n_grid=n_grid)
    theta = out["theta"]
    N = len(datasets)
    status = ["Batch_Converged"] * N
    success = list(out["converged"])
    message = ["converged (vectorised projected Levenberg-Marquardt, first-order conditions met)"] * N
    iters = list(out["iterations"])
    engine = ["batch-lm"] * N
    for k in np.nonzero(~out["converged"])[0]:  # certify or hand over to IPOPT
        pb = make_problem(datasets[k], vehicle, model, bounds, sigma=sigma, sigma_known=sigma_known)
        res = solve_ipopt(pb, theta[k])
        theta[k] = res["theta"]
        status[k], success[k], iters[k], engine[k] = res["status"], res["success"], res["iterations"], "ipopt"
        message[k] = "batch engine did not certify convergence; re-solved with IPOPT: " + res["message"]
    if model == "cohesion-free":
        theta[:, 0] = 0.0
    else:  # one-load datasets: report the same ridge marker as fit() does
        one = np.all(np.abs(load - load[:, :1]) <= 1e-9 * np.abs(load[:, :1]), axis=1) & np.array(success)
        if np.any(one):
            W1 = load[one, 0]
            fmax = vehicle.contact_area * theta[one, 0] + W1 * np.tan(theta[one, 1])
            theta[one, 0], theta[one, 1] = ridge_centre(fmax, W1, vehicle.contact_area, bounds)
    F, J = thrust_and_jacobian(theta, slip, load, l, b, model)
    r = F - force
    noise_warnings = None
    if sigma is None and not sk:
        noise_warnings = [heteroscedasticity_warning(float(bp)) for bp in heteroscedasticity(force, r, sig)]
    dt = (time.perf_counter() - t0) / max(N, 1)
    return build_results_batch(model=model, method="ipopt", theta=theta, jacobian=J / sig[:, :, None],
                               weighted_residuals=r / sig, residuals=r, normal_loads=load, vehicle=vehicle,
                               bounds=bounds, status=status, success=success, message=message, iterations=iters,
                               solve_time=[dt] * N, sigma_known=sk, extra=[{"engine": e} for e in engine],
                               warnings=noise_warnings)


def _fit_chunk(datasets, vehicle, model, method, bounds, kw, engine: str = "ipopt") -> list[FitResult]:
    from .fitting import fit
    return [fit(d, vehicle, model=model, method=method, bounds=bounds, engine=engine, **kw) for d in datasets]


class _Progress:
    def __init__(self, total: int, enabled: bool) -> None:
        self.total, self.enabled, self.done, self.t0 = total, enabled, 0, time.perf_counter()

    def update(self, k: int) -> None:
        self.done += k
        if self.enabled:
            dt = time.perf_counter() - self.t0
            rate = self.done / dt if dt > 0 else float("inf")
            line = f"fit_many: {self.done}/{self.total} fits ({rate:,.0f}/s)"
            if sys.stderr.isatty():  # a terminal: one line, rewritten in place
                sys.stderr.write("\r" + line + ("\n" if self.done >= self.total else ""))
            elif self.done >= self.total or self.done * 10 // self.total > (self.done - k) * 10 // self.total:
                sys.stderr.write(line + "\n")  # a log file: one line per tenth, no carriage returns
            sys.stderr.flush()


def fit_many(datasets: Iterable, vehicle: Vehicle, *, model: str = "full", method: str = "ipopt",
             bounds: SoilBounds = PRACTICAL_BOUNDS, executor: Executor | None = None, progress: bool = True,
             chunk_size: int | None = None, engine: str = "auto", strict: bool = False, **kw) -> list[FitResult]:
    """Fit many datasets with one vehicle; results in input order.

    Parameters
    ----------
    datasets : iterable of SlipData or DriveLog
    vehicle : Vehicle
    model, method, bounds
        As for :func:`~soiltrack.identify.fit`.
    executor : concurrent.futures.Executor, optional
        Where to run chunks (thread/process pool, ``dask.distributed.Client.get_executor()``).
        ``None``: in this process.
    progress : bool
        Print progress on stderr.
    chunk_size : int, optional
        Datasets per chunk (default: all in one chunk without an executor, else about 4 chunks
        per worker, at least 256 datasets).
    engine : {"auto", "vectorized", "compiled", "loop"}
        ``"vectorized"``: same-size slip data with ``method="ipopt"`` go through the vectorised
        engine (module docs); ``"compiled"``: one call of the compiled single-fit engine per
        dataset (:mod:`soiltrack.identify.compiled_lm`, IPOPT hand-over when not certified);
        ``"auto"``: groups of at least ``SMALL_GROUP`` same-size datasets vectorised, smaller
        groups (e.g. ``fit_many([data])``) compiled, whose fixed cost per call is lower;
        ``"loop"``: one cached-IPOPT fit per dataset.
    strict : bool
        Raise :class:`FitFailed` on the first failed fit.
    **kw
        ``sigma``, ``sigma_known``, ``n_grid`` and other options of :func:`fit`.

    Returns
    -------
    list of FitResult
    """
    datasets = list(datasets)
    check_common(vehicle, model, method, bounds)
    if engine not in ("auto", "vectorized", "compiled", "loop"):
        raise ValueError(f"engine must be 'auto', 'vectorized', 'compiled' or 'loop', got {engine!r}")
    n = len(datasets)
    prog = _Progress(n, progress)
    results: list[FitResult | None] = [None] * n
    vec = engine in ("auto", "vectorized") and method == "ipopt" and \
        set(kw) <= {"sigma", "sigma_known", "n_grid"} and np.ndim(kw.get("sigma", 0.0)) == 0
    groups: dict = {}
    singles = []
    for k, d in enumerate(datasets):
        if vec and isinstance(d, SlipData) and d.n_samples >= (3 if model == "full" else 2) and d.slip.any():
            groups.setdefault(d.n_samples, []).append(k)
        else:
            singles.append(k)
    if chunk_size is None:
        workers = getattr(executor, "_max_workers", 4) if executor is not None else 1
        chunk_size = n if executor is None else max(256, -(-n // (4 * workers)))
    chunk_size = max(1, int(chunk_size))
    if engine == "auto":  # small groups: the compiled single-fit engine has the lower fixed cost
        for key in [k for k, idx in groups.items() if len(idx) < SMALL_GROUP]:
            singles.extend(groups.pop(key))
        singles.sort()
    one_engine = "ipopt" if engine == "loop" else "compiled" if engine in ("auto", "compiled") else "ipopt"
    jobs = []  # (indices, callable, args)
    for idx in groups.values():
        for s in range(0, len(idx), chunk_size):
            part = idx[s:s + chunk_size]
            jobs.append((part, _solve_chunk, ([datasets[k] for k in part], vehicle, model, bounds,
                                              kw.get("sigma"), kw.get("sigma_known"), kw.get("n_grid", 13))))
    single_chunk = chunk_size if executor is not None else max(1, min(chunk_size, 64))
    for s in range(0, len(singles), single_chunk):
        part = singles[s:s + single_chunk]
        jobs.append((part, _fit_chunk, ([datasets[k] for k in part], vehicle, model, method, bounds, kw, one_engine)))
    if executor is None:
        for part, fn, args in jobs:
            for k, r in zip(part, fn(*args)):
                results[k] = r
            prog.update(len(part))
    else:
        futures = [(part, executor.submit(fn, *args)) for part, fn, args in jobs]
        for part, fut in futures:
            for k, r in zip(part, fut.result()):
                results[k] = r
            prog.update(len(part))
    if strict:
        for r in results:
            if r is not None and not r.success:
                raise FitFailed(r)
    return results  # type: ignore[return-value]
