"""Many fits at once: ``fit_many``.

Slip datasets fitted with ``method="ipopt"`` go through the compiled LM kernel
(:mod:`soiltrack.identify.sweep.compiled_lm`: one CasADi call per dataset, residuals and derivatives
by AD from ``soilmodel.traction.thrust_expr``, padded to a few size classes so that datasets
of many lengths share a handful of compiled Functions). With ``engine="auto"`` (default) or
``"vectorized"`` the certified results are built in one stacked numpy step per dataset length
(:func:`~soiltrack.identify.estimates.result.build_results_batch`, the same statistics as ``fit``);
``"auto"`` never waits for a C compiler (virtual machine while the C code compiles in the
background), ``"vectorized"`` compiles now if the C code is not cached. Any dataset the kernel
does not certify is re-solved with the cached IPOPT solver (said in its message,
``extra["handed_over_from"]``). ``engine="compiled"`` fits each dataset with
``fit(..., engine="compiled")``; ``engine="ipopt"`` with the cached IPOPT solver. Other
methods and drive logs go one by one through :func:`~soiltrack.identify.fit`.

Parallelism: pass any :class:`concurrent.futures.Executor`; work is submitted in chunks
(``chunk_size`` datasets each). For Dask, ``client.get_executor()`` of a
``dask.distributed.Client`` is such an executor (dask is not required). Every cached solver
is safe under threads (:mod:`soiltrack.soilmodel.threadsafe`; the compiled kernels hold their
own lock across each call) and processes (each builds or loads its own).
"""
from __future__ import annotations

import sys
import time
from concurrent.futures import Executor
from typing import Iterable, Sequence

import numpy as np

from ..soilmodel.data import SlipData
from ..soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ..soilmodel.vehicle import Vehicle
from .sweep import compiled_lm
from .engines import check_engine, jit_mode, normalise_status
from .sweep.problem import FitFailed, check_common, make_problem
from .sweep.plausibility import assess
from .estimates.records import NOT_USABLE
from .estimates.result import FitResult, build_results_batch
from .settings import SETTING_NAMES, FitSettings

__all__ = ["fit_many"]


def _solve_chunk(datasets: Sequence[SlipData], vehicle: Vehicle, model: str, bounds: SoilBounds, sigma,
                 sigma_known, settings: FitSettings) -> list[FitResult]:
    """Solve slip datasets with the compiled kernel; stacked results; IPOPT for the uncertified."""
    t0 = time.perf_counter()
    jit = jit_mode(settings.engine)
    pbs = [make_problem(d, vehicle, model, bounds, sigma=sigma, sigma_known=sigma_known) for d in datasets]
    sols = compiled_lm.solve_many(pbs, settings.n_grid, jit)
    dt = (time.perf_counter() - t0) / max(len(pbs), 1)
    out: list[FitResult | None] = [None] * len(pbs)
    groups: dict[int, list[int]] = {}
    for k, (pb, sol) in enumerate(zip(pbs, sols)):
        if sol.certified:
            groups.setdefault(pb.n, []).append(k)
        else:
            res = compiled_lm.hand_over(pb, sol, None, settings.n_grid, settings.ipopt_dict, time.perf_counter(),
                                        source="vectorized")
            out[k] = normalise_status(res)
    for idx in groups.values():
        P = [pbs[k] for k in idx]
        S = [sols[k] for k in idx]
        r = np.stack([s.residuals for s in S])
        sig = np.stack([pb.sigma for pb in P])
        extras = []
        for s in S:
            e = compiled_lm.extra_of(s)
            e["engine"] = "vectorized" if s.engine == "compiled" else "vectorized-vm"
            extras.append(e)
        # the same plausibility checks as fit (they decide success: fit and fit_many agree on it)
        status, success, message, warns = [], [], [], []
        for pb, s in zip(P, S):
            found, usable = assess(pb.slip, pb.force, pb.load, s.residuals, s.theta, vehicle, model, bounds,
                                   s.curves, s.screen, s.limit_screen)
            msg = compiled_lm.message_of(s, None).replace("compiled", "vectorised compiled", 1)
            status.append("converged" if usable else f"converged {NOT_USABLE}")
            success.append(usable)
            message.append(msg if usable else f"{msg}; the data or the answer fail the plausibility checks (see the "
                           "warnings)")
            warns.append(tuple(pb.noise_warning(s.residuals, s.bp_screen)) + found)
        built = build_results_batch(
            model=model, method="ipopt", theta=np.stack([s.theta for s in S]), jacobian=np.stack([s.jacobian for s in S]),
            weighted_residuals=r / sig, residuals=r, normal_loads=np.stack([pb.load for pb in P]), vehicle=vehicle,
            bounds=bounds, status=status, success=success, message=message,
            iterations=[s.iterations for s in S], solve_time=[dt] * len(idx), sigma_known=P[0].sigma_known,
            extra=extras, warnings=warns)
        for k, res in zip(idx, built):
            out[k] = res
    return out  # type: ignore[return-value]


def _fit_chunk(datasets, vehicle, model, method, bounds, kw, settings: FitSettings) -> list[FitResult]:
    from .fitting import fit
    return [fit(d, vehicle, model=model, method=method, bounds=bounds, settings=settings, **kw) for d in datasets]


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
             chunk_size: int | None = None, engine: str | None = None, strict: bool = False,
             settings: FitSettings | None = None, **kw) -> list[FitResult]:
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
        per worker, at most 256 datasets each).
    engine : {"auto", "ipopt", "compiled", "vectorized"}, optional
        As for :func:`~soiltrack.identify.fit` (module notes; :mod:`soiltrack.identify.engines`).
    strict : bool
        Raise :class:`FitFailed` on the first failed fit.
    settings : FitSettings, optional
        Typed solver settings; ``engine``, ``n_grid``, ``ipopt_options``, ``max_iter`` keywords
        override its fields.
    **kw
        ``sigma``, ``sigma_known`` and drive-log options of :func:`fit`.

    Returns
    -------
    list of FitResult
    """
    datasets = list(datasets)
    check_common(vehicle, model, method, bounds)
    given = {k: kw.pop(k) for k in SETTING_NAMES if k in kw}
    st = FitSettings.resolve(settings, engine=engine, **given)
    check_engine(st.engine)
    n = len(datasets)
    prog = _Progress(n, progress)
    results: list[FitResult | None] = [None] * n
    kernel_ok = st.engine in ("auto", "vectorized") and method == "ipopt" and set(kw) <= {"sigma", "sigma_known"}
    batched, singles = [], []
    for k, d in enumerate(datasets):
        (batched if kernel_ok and isinstance(d, SlipData) else singles).append(k)
    if chunk_size is None:
        workers = getattr(executor, "_max_workers", 4) if executor is not None else 1
        chunk_size = n if executor is None else max(1, min(256, -(-n // (4 * workers))))
    chunk_size = max(1, int(chunk_size))
    jobs = []  # (indices, callable, args)
    # batched: sorted by length so that a chunk holds few lengths (one stacked result step each)
    batched.sort(key=lambda k: datasets[k].n_samples)
    for s in range(0, len(batched), chunk_size):
        part = batched[s:s + chunk_size]
        jobs.append((part, _solve_chunk, ([datasets[k] for k in part], vehicle, model, bounds, kw.get("sigma"),
                                          kw.get("sigma_known"), st)))
    for s in range(0, len(singles), chunk_size):
        part = singles[s:s + chunk_size]
        jobs.append((part, _fit_chunk, ([datasets[k] for k in part], vehicle, model, method, bounds, kw, st)))
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
