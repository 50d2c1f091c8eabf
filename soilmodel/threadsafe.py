"""Thread and fork safety for cached CasADi solvers: one home for the lock and the cache.

A cached ``nlpsol``/``rootfinder``/``integrator`` is shared state. IPOPT's linear solver
(MUMPS) keeps global Fortran state, so two solves in two threads of one process can crash
the process (measured: ``fit`` from a ``ThreadPoolExecutor(4)`` ended in a segmentation
fault); and ``solver.stats()`` read after a call may belong to another thread's solve.
Every solver call in the library therefore goes through :func:`call_solver`, which holds
one process-wide re-entrant lock across the call and the ``stats()`` read, and every solver
builder is wrapped in :func:`locked_cache`, which builds each solver once under the same lock.
Threads then serialise on the solve itself (parallelism comes from processes, or from the
compiled engines that keep their own memory per call); processes each hold their own cache.

Fork safety (``os.register_at_fork``): a process forked while another thread is inside an
IPOPT solve would inherit the lock held by a thread that does not exist in the child, and
the solver's native state in the middle of that solve (measured before this module handled
it: a fork ``ProcessPoolExecutor`` created beside three threads running IPOPT returned no
result in 7 of 10 tries). ``identify.fit`` holds the lock for the whole fit, not only its solves (a
thread in the middle of a fit's other CasADi or BLAS work at the fork: 1 hang in 5 tries under a
load of 10). So a fork waits until no fit or solve is running (the forking thread takes
:data:`SOLVER_LOCK` just before the fork and releases it in the parent just after), and the
child re-creates the lock, empties every :func:`locked_cache` (its solvers are rebuilt on first
use, in the child, from scratch) and gives every ``functools.cached_property`` of the library a
fresh lock (Python 3.11 shares one lock per property among all instances: a thread computing a fit
result's statistics at the fork left a worker hung in ``cached_property.__get__``, 1 of 25 tries).
The spawn and forkserver start methods never copy this state and need none of it.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import threading
import weakref
from typing import Any, Callable, Iterator, TypeVar

__all__ = [
    "SOLVER_LOCK",
    "call_solver",
    "best_of_starts",
    "CONVERGED_STATUS",
    "solver_status",
    "locked_cache",
    "solver_lock",
    "fork_generation",
    "fit_section",
]

#: The process-wide lock held across every cached-solver call and its ``stats()`` read
#: (re-created in a forked child: read it through :func:`solver_lock`, never keep a copy).
SOLVER_LOCK = threading.RLock()

T = TypeVar("T")

_CACHES: "weakref.WeakSet[Any]" = weakref.WeakSet()  # every locked_cache wrapper, emptied in a forked child
_GENERATION = [0]  # forks this process descends from (0 in a process not forked from a soiltrack process)


def solver_lock() -> threading.RLock:
    """The current process's :data:`SOLVER_LOCK` (a forked child has its own, fresh one)."""
    return SOLVER_LOCK


def fork_generation() -> int:
    """How many forks separate this process from the one that imported the module (0: not forked)."""
    return _GENERATION[0]


#: Open (set) except while a fork waits for the lock: a thread starting a new fit waits here, so that
#: threads fitting back to back cannot starve the fork (the lock is not fair).
_FORK_GATE = threading.Event()
_FORK_GATE.set()
_DEPTH = threading.local()  # fit sections this thread is inside (a nested fit never waits at the gate)


def _before_fork() -> None:  # no solve in flight while the address space is copied
    _FORK_GATE.clear()
    SOLVER_LOCK.acquire()


def _after_fork_parent() -> None:
    SOLVER_LOCK.release()
    _FORK_GATE.set()


@contextlib.contextmanager
def fit_section() -> Iterator[None]:
    """Hold :data:`SOLVER_LOCK` across a whole fit (its CasADi and BLAS work, not only its solves).

    A fork then never copies a thread in the middle of a fit; a thread starting a new top-level
    fit first waits while a fork is pending, so fits back to back cannot starve the fork.
    """
    depth = getattr(_DEPTH, "n", 0)
    if depth == 0:
        _FORK_GATE.wait()
    _DEPTH.n = depth + 1
    try:
        with SOLVER_LOCK:
            yield
    finally:
        _DEPTH.n = depth


def _renew_cached_property_locks() -> None:
    """Fresh locks for the library's ``functools.cached_property`` descriptors (Python < 3.12 keeps one
    RLock per descriptor, shared by all instances: held by another thread at the fork, it would never
    be released in the child - measured: a worker hung in ``cached_property.__get__`` of a fit result)."""
    package = __name__.rsplit(".", 2)[0]
    for name, module in list(sys.modules.items()):
        if module is None or not (name == package or name.startswith(package + ".")):
            continue
        for obj in list(vars(module).values()):
            if isinstance(obj, type) and obj.__module__ == name:
                for attr in vars(obj).values():
                    if isinstance(attr, functools.cached_property) and hasattr(attr, "lock"):
                        attr.lock = threading.RLock()


def _after_fork_child() -> None:
    global SOLVER_LOCK, _FORK_GATE, _DEPTH
    SOLVER_LOCK = threading.RLock()
    _FORK_GATE = threading.Event()
    _FORK_GATE.set()
    _DEPTH = threading.local()
    _GENERATION[0] += 1
    for wrapper in list(_CACHES):
        wrapper.cache_clear()
    _renew_cached_property_locks()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_before_fork, after_in_parent=_after_fork_parent, after_in_child=_after_fork_child)


def locked_cache(maxsize: int | None = 128) -> Callable[[Callable[..., T]], Callable[..., T]]:
    """Like ``functools.lru_cache``, but builds under :data:`SOLVER_LOCK` (once per key).

    The cache is emptied in a forked child (its solvers are rebuilt there on first use).
    """

    def deco(builder: Callable[..., T]) -> Callable[..., T]:
        cached = functools.lru_cache(maxsize=maxsize)(builder)

        @functools.wraps(builder)
        def wrapper(*args: Any, **kwargs: Any) -> T:
            with SOLVER_LOCK:
                return cached(*args, **kwargs)

        wrapper.cache_clear = cached.cache_clear  # type: ignore[attr-defined]
        wrapper.cache_info = cached.cache_info  # type: ignore[attr-defined]
        _CACHES.add(wrapper)
        return wrapper

    return deco


def call_solver(solver: Any, *args: Any, **kwargs: Any) -> tuple[Any, dict]:
    """Call a CasADi solver and read its ``stats()`` under :data:`SOLVER_LOCK`.

    Returns ``(output, stats)``; the stats are those of this very call.
    """
    with SOLVER_LOCK:
        out = solver(*args, **kwargs)
        try:
            stats = dict(solver.stats())
        except Exception:  # noqa: BLE001 - Functions without stats (plain SX/MX) have none
            stats = {}
    return out, stats


#: IPOPT return statuses that count as a converged solve for :func:`best_of_starts`.
CONVERGED_STATUS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


def solver_status(stats: dict) -> tuple[str, int, bool]:
    """``(return status, iterations, converged)`` read from an IPOPT call's ``stats``.

    Converged: IPOPT's ``success`` flag and a status in :data:`CONVERGED_STATUS` (the caller adds its own
    checks of the answer: finite numbers, inside the bounds).
    """
    status = str(stats.get("return_status", "unknown"))
    return status, int(stats.get("iter_count", -1)), bool(stats.get("success", False)) and status in CONVERGED_STATUS


def best_of_starts(solver: Any, x0s: Any, **kwargs: Any) -> tuple[tuple, int]:
    """Solve from every start ``x0`` (the solver's own variables); the best and how many converged.

    The best is ``(failed, f, x, status, iterations)``: a converged solve (:data:`CONVERGED_STATUS`, finite
    objective) before any other, then the least objective. ``kwargs`` go to every call (``p``, ``lbx``, ...).
    """
    import math

    import numpy as np

    best, n_ok = None, 0
    for x0 in x0s:
        sol, stats = call_solver(solver, x0=x0, **kwargs)
        f = float(sol["f"])
        status, iters, converged = solver_status(stats)
        ok = converged and math.isfinite(f)
        n_ok += ok
        cand = (not ok, f, np.asarray(sol["x"], dtype=float).ravel(), status, iters)
        if best is None or cand[:2] < best[:2]:
            best = cand
    if best is None:
        raise ValueError("no start to solve from")
    return best, n_ok
