"""Thread safety for cached CasADi solvers: one home for the lock and the cache.

A cached ``nlpsol``/``rootfinder``/``integrator`` is shared state. IPOPT's linear solver
(MUMPS) keeps global Fortran state, so two solves in two threads of one process can crash
the process (measured: ``fit`` from a ``ThreadPoolExecutor(4)`` ended in a segmentation
fault); and ``solver.stats()`` read after a call may belong to another thread's solve.
Every solver call in the library therefore goes through :func:`call_solver`, which holds
one process-wide re-entrant lock across the call and the ``stats()`` read, and every solver
builder is wrapped in :func:`locked_cache`, which builds each solver once under the same lock.
Threads then serialise on the solve itself (parallelism comes from processes, or from the
compiled engines that keep their own memory per call); processes each hold their own cache.
"""
from __future__ import annotations

import functools
import threading
from typing import Any, Callable, TypeVar

__all__ = ["SOLVER_LOCK", "call_solver", "locked_cache"]

#: The process-wide lock held across every cached-solver call and its ``stats()`` read.
SOLVER_LOCK = threading.RLock()

T = TypeVar("T")


def locked_cache(maxsize: int | None = 128) -> Callable[[Callable[..., T]], Callable[..., T]]:
    """Like ``functools.lru_cache``, but builds under :data:`SOLVER_LOCK` (once per key)."""

    def deco(builder: Callable[..., T]) -> Callable[..., T]:
        cached = functools.lru_cache(maxsize=maxsize)(builder)

        @functools.wraps(builder)
        def wrapper(*args: Any, **kwargs: Any) -> T:
            with SOLVER_LOCK:
                return cached(*args, **kwargs)

        wrapper.cache_clear = cached.cache_clear  # type: ignore[attr-defined]
        wrapper.cache_info = cached.cache_info  # type: ignore[attr-defined]
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
