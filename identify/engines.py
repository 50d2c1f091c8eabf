"""The engine vocabulary, shared by ``fit``, ``fit_many`` and ``soiltrack fit --engine``.

An *engine* is what solves the bounded weighted least-squares problem of ``method="ipopt"`` on
tractive force-slip data. The estimator and its optimum are the same whichever engine runs;
IPOPT is the authority the others hand over to when they cannot certify their answer.

``"auto"`` (default)
    The compiled LM engine without ever waiting for a C compiler: C code from the per-user
    disk cache when it is there, else CasADi's virtual machine (same Function, same numbers)
    while a detached compiler fills the cache for the next call (:mod:`.jitcache`).
    ``fit_many`` solves slip datasets this way and builds their results in one stacked step.
``"ipopt"``
    The cached IPOPT solver for every dataset (what ``fit_many(engine="loop")`` used to be).
``"compiled"``
    The compiled LM engine (:mod:`.sweep.compiled_lm`), C code compiled now if not cached (about a
    second, once per machine and size class), one result at a time.
``"vectorized"``
    For many datasets (``fit_many``): the compiled LM kernel on each dataset back to back,
    the results (statistics, identifiability) built in one stacked numpy step; compiled now
    if not cached. On a single dataset it is the compiled engine.

What actually solved a fit is in ``result.extra["engine"]``: ``"ipopt"``, ``"compiled"``
(C code), ``"compiled-vm"`` (the same Function in CasADi's virtual machine: no C compiler,
``SOILTRACK_NO_JIT``, or C code still compiling), ``"vectorized"`` or ``"vectorized-vm"``;
``extra["engine_backend"]`` says why, ``extra["handed_over_from"]`` names the engine that
handed a fit to IPOPT. ``result.status`` is ``"converged"`` for every certified optimum,
whatever solved it; a failure keeps IPOPT's status. The solver's own word is in
``extra["solver_status"]``.
"""

from __future__ import annotations

from ..soilmodel.errors import DataError

__all__ = ["ENGINES", "DEFAULT_ENGINE", "CONVERGED", "check_engine", "jit_mode", "normalise_status"]

#: Engine names accepted by ``fit``, ``fit_many`` and the command line.
ENGINES = ("auto", "ipopt", "compiled", "vectorized")
#: The default engine everywhere.
DEFAULT_ENGINE = "auto"
#: ``result.status`` of every certified optimum.
CONVERGED = "converged"


def check_engine(engine: str) -> str:
    """Return ``engine`` if it is one of :data:`ENGINES`, else raise :class:`DataError`."""
    if engine not in ENGINES:
        hint = " ('loop' is now 'ipopt')" if engine == "loop" else ""
        raise DataError(f"unknown engine {engine!r}{hint}; expected one of {ENGINES}")
    return engine


def jit_mode(engine: str) -> str:
    """How the compiled engines obtain C code for ``engine``: ``"background"`` for auto, else ``"wait"``."""
    return "background" if engine == "auto" else "wait"


def normalise_status(res, engine_label: str | None = None):
    """Give an IPOPT result the shared status vocabulary (``"converged"``; IPOPT's word in ``extra``)."""
    raw = res.status
    res.extra.setdefault("solver_status", raw)
    if engine_label is not None:
        res.extra["engine"] = engine_label
    if res.success and raw != CONVERGED:
        object.__setattr__(res, "status", CONVERGED)  # FitResult is frozen; status is a plain field
    return res
