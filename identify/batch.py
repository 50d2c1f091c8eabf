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
own lock across each call) and processes (each builds or loads its own; a fork start method is
safe beside solver threads, :mod:`soiltrack.soilmodel.threadsafe`).

Nothing is lost (issue 23): there is one result per item, in input order. An item that cannot
be fitted (not SlipData or DriveLog, too few samples, any error while fitting it) gives a
failed :class:`FitResult` (``success`` False, ``status`` "not fitted", the reason and its batch
index in ``message``, ``extra["batch_index"]`` and ``extra["error"]``); the batch goes on. When a
process-pool worker dies (``BrokenProcessPool``: killed, out of memory, a crash in native code),
the finished results are kept and the items the pool lost are run again in a fresh pool of the
same kind, a few at a time; the items in flight when a fresh pool breaks again are each run
alone, so an item that kills its worker costs only itself (reported failed, "its worker process
died"). Items of a chunk that failed in another executor (a Dask worker lost, a pickling error)
are retried one by one in the same executor. Every result carries the data-consistency checks
(:mod:`soiltrack.identify.consistency`, repeated rows included), as ``fit`` gives them.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from dataclasses import replace
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, as_completed, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ..soilmodel.data import DriveLog, SlipData
from ..soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ..soilmodel.vehicle import Vehicle
from .sweep import compiled_lm
from .engines import check_engine, jit_mode, normalise_status
from .sweep.problem import FitFailed, check_common, checked_problem, checked_problems
from ..soilmodel.ridge import continuous_load
from .sweep.plausibility import assess_many
from .sweep.model import SweepResiduals
from .estimates.records import NOT_USABLE
from .estimates.result import FitResult, build_results_batch
from .settings import SETTING_NAMES, FitSettings
from .consistency import check_consistency_many, with_consistency
from .estimates.result import build_result
from .fitting import fit
from .sweep.resistance import assumed_resistance
from .sweep.rig import load_separation, repeat_free, rig_extra, std_weights

__all__ = ["fit_many", "failed_result"]


def failed_result(
    index: int,
    data: Any,
    vehicle: Vehicle,
    model: str,
    method: str,
    bounds: SoilBounds,
    reason: str,
    error: str = "",
) -> FitResult:
    """The failed :class:`FitResult` of batch item ``index``: no estimate, ``success`` False, the reason said.

    ``message`` is ``"batch item <index> (<source>): <reason>"``; ``extra`` holds ``batch_index``
    and ``error`` (the exception's type name, when one was raised).
    """
    src = os.fspath(data) if isinstance(data, (str, os.PathLike)) else getattr(data, "source", None)
    where = f"batch item {index}" + (f" ({src})" if isinstance(src, str) else f" (a {type(data).__name__})")
    kind = "drive" if isinstance(data, DriveLog) else "slip"
    res = build_result(
        data_kind=kind,
        model=model,
        method=method,
        theta=np.full(3, np.nan),
        jacobian=np.zeros((0, 3)),
        weighted_residuals=np.zeros(0),
        residuals=np.zeros(0),
        residual_unit="N" if kind == "slip" else "m/s",
        n_samples=0,
        normal_loads=np.zeros(0),
        vehicle=vehicle,
        bounds=bounds,
        status="not fitted",
        success=False,
        message=f"{where}: {reason}",
        iterations=0,
        solve_time=0.0,
        extra={"batch_index": int(index), "error": error},
        residual_model=SweepResiduals() if kind == "slip" else None,
    )
    return replace(res, status="not fitted")  # nothing was solved: no "non-finite numbers" suffix


def _guarded_fit(
    k: int,
    d: Any,
    vehicle: Vehicle,
    model: str,
    method: str,
    bounds: SoilBounds,
    kw: dict,
    settings: FitSettings,
    segments: str | float | None = None,
    topics: Any = None,
) -> Any:
    """``fit`` of one item; any error becomes a failed result naming the item (never raised).

    A path is read here (in the worker: :func:`~soiltrack.soilmodel.logread.read_data`, a CSV or a ROS bag);
    a drive log gets ``extra["log_span"]`` (:func:`~.segments.log_span`), or with ``segments`` its soil map
    (:func:`~.segments.fit_segments`, a :class:`~.segments.SegmentMap`).
    """
    if isinstance(d, (str, os.PathLike)):
        try:
            from ..soilmodel.logread import read_data

            d = read_data(d, topics=topics if topics is not None and _is_bag(d) else None)
        except Exception as e:  # noqa: BLE001 - a log that cannot be read is this item's failure only
            return _failure(k, d, vehicle, model, method, bounds, e, read=True)
    if not isinstance(d, (SlipData, DriveLog)):
        return failed_result(
            k,
            d,
            vehicle,
            model,
            method,
            bounds,
            f"fit takes SlipData or DriveLog, got {type(d).__name__}",
            "DataError",
        )
    try:
        if segments is not None and isinstance(d, DriveLog):
            from .segments import fit_segments

            return fit_segments(d, vehicle, segments, model=model, bounds=bounds, **kw)
        res = fit(d, vehicle, model=model, method=method, bounds=bounds, settings=settings, **kw)
    except Exception as e:  # noqa: BLE001 - one bad item never aborts the batch (module notes)
        return _failure(k, d, vehicle, model, method, bounds, e)
    if isinstance(d, DriveLog):
        from .segments import log_span

        res.extra["log_span"] = log_span(d)  # the result's own, fresh dict
    return res


def _is_bag(path: Any) -> bool:
    from ..soilmodel.logread import is_bag

    return is_bag(path)


def _failure(
    k: int, d: Any, vehicle: Vehicle, model: str, method: str, bounds: SoilBounds, e: Exception, *, read: bool = False
) -> FitResult:
    """The failed result of item ``k`` from the error ``e``: its reason and column; reading errors (``read``) in
    full (the file, column and rows they name)."""
    reason = getattr(e, "reason", None) or str(e) or type(e).__name__
    col = getattr(e, "column", None)
    why = str(e) if read else (f"column '{col}': " if col else "") + reason
    return failed_result(k, d, vehicle, model, method, bounds, why, type(e).__name__)


def _solve_chunk(
    indices: Sequence[int],
    datasets: Sequence[SlipData],
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    sigma,
    sigma_known,
    settings: FitSettings,
) -> list[FitResult]:
    """Solve slip datasets with the compiled kernel; stacked results; IPOPT for the uncertified.

    An item whose problem cannot be set up is fitted alone (:func:`_guarded_fit`: its error becomes
    its failed result); if the stacked solve itself fails, every item is fitted alone.
    """
    kw = {k: v for k, v in (("sigma", sigma), ("sigma_known", sigma_known)) if v is not None}
    pbs, keep = [], []
    out: list[FitResult | None] = [None] * len(datasets)
    check_common(vehicle, model, "ipopt", bounds)  # once for the chunk (a worker's chunk is checked there too)
    # plain sweeps set up for a length at once; any other item alone (the same problems)
    bulk = checked_problems(list(datasets), vehicle, model, bounds, sigma_known) if sigma is None else None
    for j, d in enumerate(datasets):
        try:
            pb = bulk[j] if bulk is not None else None
            pbs.append(pb if pb is not None else checked_problem(d, vehicle, model, bounds, sigma, sigma_known))
            keep.append(j)
        except Exception:  # noqa: BLE001 - said by the single fit below, with the item's index
            out[j] = _guarded_fit(indices[j], d, vehicle, model, "ipopt", bounds, kw, settings)
    try:
        solved = _solve_problems(pbs, [datasets[j] for j in keep], vehicle, model, bounds, settings)
    except Exception:  # noqa: BLE001 - a failed stacked step: each item alone, errors per item
        solved = [_guarded_fit(indices[j], datasets[j], vehicle, model, "ipopt", bounds, kw, settings) for j in keep]
    for j, res in zip(keep, solved):
        out[j] = res
    return out  # type: ignore[return-value]


def _solve_problems(
    pbs: list,
    datasets: list[SlipData],
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    settings: FitSettings,
) -> list[FitResult]:
    """The compiled kernel over set-up problems; consistency checks applied as ``fit`` applies them."""
    t0 = time.perf_counter()
    jit = jit_mode(settings.engine)
    if not pbs:
        return []
    sols = compiled_lm.solve_many(pbs, settings.n_grid, jit)
    dt = (time.perf_counter() - t0) / max(len(pbs), 1)
    out: list[FitResult | None] = [None] * len(pbs)
    groups: dict[int, list[int]] = {}
    for k, (pb, sol) in enumerate(zip(pbs, sols)):
        if sol.certified:
            groups.setdefault(pb.n, []).append(k)
        else:
            res = compiled_lm.hand_over(
                pb, sol, None, settings.n_grid, settings.ipopt_dict, time.perf_counter(), source="vectorized"
            )
            out[k] = normalise_status(res)
    no_repeats = [False] * len(pbs)  # found in bulk: no slip repeats (no pure-error test to run)
    for idx in groups.values():
        P = [pbs[k] for k in idx]
        S = [sols[k] for k in idx]
        for k, free in zip(idx, repeat_free(np.stack([pb.slip for pb in P])).tolist()):
            no_repeats[k] = free
        r = np.stack([s.residuals for s in S])
        sig = np.stack([pb.sigma for pb in P])
        theta = np.stack([s.theta for s in S])
        loads = np.stack([pb.load for pb in P])
        extras = []
        for pb, s in zip(P, S):
            e = compiled_lm.extra_of(s)  # a new dict; as fit's compiled path records it
            e["sigma_model"] = pb.noise_model
            e["engine"] = "vectorized" if s.engine == "compiled" else "vectorized-vm"
            extras.append(e)
        # the same plausibility checks as fit (they decide success: fit and fit_many agree on it)
        status, success, message, warns = [], [], [], []
        messages: dict[bool, str] = {}  # the message depends on the solve only through one_load
        for pb, s, (found, usable) in zip(P, S, assess_many(P, S, vehicle, model, bounds, (theta, loads, r))):
            msg = messages.get(s.one_load)
            if msg is None:
                msg = compiled_lm.message_of(s, None).replace("compiled", "vectorised compiled", 1)
                messages[s.one_load] = msg
            status.append("converged" if usable else f"converged {NOT_USABLE}")
            success.append(usable)
            message.append(
                msg if usable else f"{msg}; the data or the answer fail the plausibility checks (see the warnings)"
            )
            warns.append(tuple(pb.noise_warning(s.residuals, s.bp_screen)) + found)
        built = build_results_batch(
            model=model,
            method="ipopt",
            theta=theta,
            jacobian=np.stack([s.jacobian for s in S]),
            weighted_residuals=r / sig,
            residuals=r,
            normal_loads=loads,
            vehicle=vehicle,
            bounds=bounds,
            status=status,
            success=success,
            message=message,
            iterations=[s.iterations for s in S],
            solve_time=[dt] * len(idx),
            sigma_known=P[0].sigma_known,
            extra=extras,
            warnings=warns,
            residual_model=SweepResiduals(),
        )
        for k, res in zip(idx, built):
            out[k] = res
    return [
        with_consistency(_with_rig_extra(res, d, model, nr), report)  # type: ignore
        for res, d, nr, report in zip(out, datasets, no_repeats, check_consistency_many(datasets, vehicle))
    ]


def _kernel_fits_like_fit(d: Any, model: str) -> bool:
    """Whether ``fit`` would solve ``d`` as the stacked kernel does: a plain slip sweep (not a rig sweep -
    no per-row std weights, no dropped rows, no measured load per row - and no load spread so small that
    ``fit`` takes the profile-likelihood intervals)."""
    if not isinstance(d, SlipData):
        return False
    if d.force_std is not None or d.dropped or (d.normal_load is not None and continuous_load(d.normal_load)):
        return False  # a rig sweep takes fit's rig path: weights, extras
    try:
        if std_weights(d) is not None:
            return False
        sep = load_separation(d) if model == "full" else None
    except Exception:  # noqa: BLE001 - fitted alone, where the error is said
        return False
    return sep is None or not sep.fragile


def _with_rig_extra(res: FitResult, d: SlipData, model: str, no_repeats: bool = False) -> FitResult:
    """What ``fit`` adds to a rig sweep's ``extra`` (:func:`~.sweep.rig.rig_extra`: the pure-error test over
    repeated slips, the load separation; the assumed resistance of drawbar-pull data), on a kernel result
    (``no_repeats``: :func:`~.sweep.rig.repeat_free` found no repeated slip)."""
    more = rig_extra(d, res, load_separation(d) if model == "full" else None, no_repeats=no_repeats)
    if d.measured == "drawbar_pull":
        more["resistance"] = assumed_resistance(res)
    if more:
        res.extra.update(more)  # the result's own, fresh dict
    return res


def _fit_chunk(
    indices: Sequence[int],
    datasets,
    vehicle,
    model,
    method,
    bounds,
    kw,
    settings: FitSettings,
    segments=None,
    topics=None,
) -> list[Any]:
    """``fit`` of each item, errors per item (:func:`_guarded_fit`)."""
    return [
        _guarded_fit(k, d, vehicle, model, method, bounds, kw, settings, segments, topics)
        for k, d in zip(indices, datasets)
    ]


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


def fit_many(
    datasets: Iterable,
    vehicle: Vehicle,
    *,
    model: str = "full",
    method: str = "ipopt",
    bounds: SoilBounds = PRACTICAL_BOUNDS,
    executor: Executor | None = None,
    progress: bool = True,
    chunk_size: int | None = None,
    engine: str | None = None,
    strict: bool = False,
    settings: FitSettings | None = None,
    out: str | os.PathLike | None = None,
    segments: str | float | None = None,
    topics: Any = None,
    **kw,
) -> list[Any]:
    """Fit many datasets with one vehicle; results in input order.

    Parameters
    ----------
    datasets : iterable of SlipData, DriveLog or paths
        A path (str or PathLike: a CSV or a ROS bag) is read where it is fitted (in the worker);
        a file that cannot be read gives a failed result with the reader's message.
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
        Raise :class:`FitFailed` on the first failed fit (after the whole batch has run).
    settings : FitSettings, optional
        Typed solver settings; ``engine``, ``n_grid``, ``ipopt_options``, ``max_iter`` keywords
        override its fields.
    out : path, optional
        Write one row per item (per segment with ``segments``) to this CSV file as the fits finish
        (:mod:`soiltrack.identify.fleet`; ``*.parquet`` needs pyarrow). The file is created before any fit.
    segments : str or float, optional
        Fit each drive log segment by segment (``"60s"``, ``"auto"``: :func:`~.segments.fit_segments`);
        such an item's result is its :class:`~.segments.SegmentMap`.
    topics : str, dict or path, optional
        The mapping of the ROS bags among the paths (:func:`~soiltrack.soilmodel.rosbag_read.parse_topics`),
        one for every bag; CSV paths ignore it.
    **kw
        ``sigma``, ``sigma_known`` and drive-log options of :func:`fit`.

    Returns
    -------
    list of FitResult (or SegmentMap with ``segments``)
        One per item, in input order; an item that could not be fitted has a failed result
        (``status`` "not fitted", its index in ``message`` and ``extra["batch_index"]``).
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
    batched: list[int] = []
    singles: list[int] = []
    for k, d in enumerate(datasets):
        (batched if kernel_ok and _kernel_fits_like_fit(d, model) else singles).append(k)
    if chunk_size is None:
        workers = getattr(executor, "_max_workers", 4) if executor is not None else 1
        chunk_size = n if executor is None else max(1, min(256, -(-n // (4 * workers))))
        if out is not None and batched == [] and executor is None:
            chunk_size = 1  # a results file: each log's row written when it finishes
    chunk_size = max(1, int(chunk_size))
    # batched: sorted by length so that a chunk holds few lengths (one stacked result step each)
    batched.sort(key=lambda k: datasets[k].n_samples)
    slip_args = (vehicle, model, bounds, kw.get("sigma"), kw.get("sigma_known"), st)
    one_args = (vehicle, model, method, bounds, kw, st, segments, topics)
    jobs = _chunked(batched, chunk_size, _solve_chunk, datasets, slip_args)
    jobs += _chunked(singles, chunk_size, _fit_chunk, datasets, one_args)
    from .fleet import FleetWriter, fleet_rows

    # a results file is opened before any fit (refused when pyarrow is missing or the path is not writable)
    writer = FleetWriter(out) if out is not None else None

    def store(part: Sequence[int], res: list[Any]) -> None:
        for k, r in zip(part, res):
            results[k] = r
            if writer is not None:
                writer.write(fleet_rows(k, datasets[k], r))
        prog.update(len(part))

    def single(k: int) -> tuple[Callable, tuple]:  # one item as its own job (retries)
        return _fit_chunk, ([k], [datasets[k]], *one_args)

    def dead(k: int, why: str, error: str) -> FitResult:
        return failed_result(k, datasets[k], vehicle, model, method, bounds, why, error)

    with writer if writer is not None else contextlib.nullcontext():
        if executor is None:
            for part, fn, args in jobs:
                store(part, fn(part, *args))
        else:
            _run_on_executor(executor, jobs, store, single, dead)
    if strict:
        for r in results:
            if isinstance(r, FitResult) and not r.success:
                raise FitFailed(r)
    return results  # type: ignore[return-value]


def _chunked(indices: list[int], size: int, fn: Callable, datasets: list, args: tuple) -> list[tuple]:
    """Jobs ``(part, fn, (its datasets, *args))`` of at most ``size`` items each."""
    parts = [indices[s : s + size] for s in range(0, len(indices), size)]
    return [(part, fn, ([datasets[k] for k in part], *args)) for part in parts]


def _run_on_executor(executor: Executor, jobs: list, store: Callable, single: Callable, dead: Callable) -> None:
    """Run ``jobs`` on ``executor``: finished results kept, lost jobs' items recovered (module notes)."""
    futures: list[tuple[list[int], Future | None, BaseException | None]] = []
    for part, fn, args in jobs:
        try:
            futures.append((part, executor.submit(fn, part, *args), None))
        except Exception as e:  # noqa: BLE001 - e.g. a pool already broken by a dead worker
            futures.append((part, None, e))
    lost: list[int] = []
    broken = False
    last_error: BaseException | None = None
    parts = {fut: part for part, fut, _ in futures if fut is not None}
    for part, fut, err in futures:
        if fut is None:  # never submitted
            lost.extend(part)
            broken = broken or isinstance(err, BrokenProcessPool)
            last_error = err
    for fut in as_completed(parts):  # stored as they finish (a results file gets each row when it is ready)
        part = parts.pop(fut)
        try:
            res = fut.result()
        except Exception as e:  # noqa: BLE001 - the chunk is lost, its items are recovered below
            lost.extend(part)
            broken = broken or isinstance(e, BrokenProcessPool)
            last_error = e
        else:
            store(part, res)
    if not lost:
        return
    lost.sort()
    if broken and isinstance(executor, ProcessPoolExecutor):
        _recover_in_fresh_pools(executor, lost, store, single, dead)
        return
    for k in lost:  # another executor (threads, Dask): each item once more, alone, in the same executor
        fn, args = single(k)
        try:
            store([k], executor.submit(fn, *args).result())
        except Exception as e:  # noqa: BLE001 - reported as this item's failure
            store(
                [k],
                [
                    dead(
                        k,
                        f"its chunk failed in the executor ({type(last_error).__name__}: {last_error}) and "
                        f"so did a retry alone ({type(e).__name__}: {e})",
                        type(e).__name__,
                    )
                ],
            )


def _fresh_pool(like: ProcessPoolExecutor, workers: int) -> ProcessPoolExecutor:
    """A new process pool of the same start method and initializer as ``like``."""
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=getattr(like, "_mp_context", None),
        initializer=getattr(like, "_initializer", None),
        initargs=getattr(like, "_initargs", ()),
    )


def _recover_in_fresh_pools(
    like: ProcessPoolExecutor, items: list[int], store: Callable, single: Callable, dead: Callable
) -> None:
    """Items a broken pool lost, run again in fresh pools: at most ``workers`` in flight, so that when a
    pool breaks again only the items in flight are suspects; each suspect then runs alone in its own
    one-worker pool, and one that breaks that too is reported (its worker died twice)."""
    workers = max(1, int(getattr(like, "_max_workers", 1)))
    todo = list(items)
    while todo:
        pool = _fresh_pool(like, workers)
        suspects: list[int] = []
        try:
            flight: dict[Future, int] = {}
            while todo or flight:
                while todo and len(flight) < workers:
                    k = todo.pop(0)
                    fn, args = single(k)
                    flight[pool.submit(fn, *args)] = k
                done, _ = wait(list(flight), return_when=FIRST_COMPLETED)
                for fut in done:
                    k = flight.pop(fut)
                    try:
                        store([k], fut.result())
                    except BrokenProcessPool:
                        suspects.append(k)
                    except Exception as e:  # noqa: BLE001 - not a dead worker: this item's own failure
                        store(
                            [k],
                            [
                                dead(
                                    k,
                                    f"failed in a worker process ({type(e).__name__}: {e})",
                                    type(e).__name__,
                                )
                            ],
                        )
                if suspects:
                    suspects.extend(flight.values())  # in flight when the pool broke
                    break
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        for k in sorted(set(suspects)):
            alone = _fresh_pool(like, 1)
            try:
                fn, args = single(k)
                store([k], alone.submit(fn, *args).result())
            except BrokenProcessPool:
                store(
                    [k],
                    [
                        dead(
                            k,
                            "its worker process died twice (BrokenProcessPool: killed, out of memory, or a "
                            "crash in native code while fitting this item); fit it alone to see why",
                            "BrokenProcessPool",
                        )
                    ],
                )
            except Exception as e:  # noqa: BLE001 - reported as this item's failure
                store([k], [dead(k, f"failed in a worker process ({type(e).__name__}: {e})", type(e).__name__)])
            finally:
                alone.shutdown(wait=True, cancel_futures=True)
