"""Typed settings of a fit: :class:`FitSettings` (engine, start grid, IPOPT options, iterations).

``fit(data, vehicle, settings=FitSettings(engine="ipopt", n_grid=41))`` and the keyword form
``fit(data, vehicle, engine="ipopt", n_grid=41)`` are the same; keywords override the fields
of a given ``settings``. Unknown keywords and bad values raise :class:`DataError` naming the
argument. Data options (``sigma``, ``sigma_known``) describe the data, not the solver, and
stay keywords of ``fit``; drive-log options are passed on to the drive-log fit.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from functools import lru_cache
from typing import Any, Mapping

from ..soilmodel.errors import DataError
from .engines import DEFAULT_ENGINE, check_engine

__all__ = ["FitSettings", "SETTING_NAMES"]


@dataclass(frozen=True)
class FitSettings:
    """How a slip-data fit is solved (the estimator and its optimum do not depend on it).

    Attributes
    ----------
    engine : {"auto", "ipopt", "compiled", "vectorized"}
        What solves ``method="ipopt"`` (see :mod:`soiltrack.identify.engines`).
    n_grid : int
        K values of the variable-projection start grid (default 25).
    ipopt_options : tuple of (name, value)
        IPOPT options, e.g. ``(("ipopt.max_iter", 500),)``; a dict is accepted and stored sorted.
    max_iter : int or None
        Iteration limit of the seed's methods (``newton``: 50, ``least-squares``: 500 if None).
    """

    engine: str = DEFAULT_ENGINE
    n_grid: int = 25
    ipopt_options: tuple = ()
    max_iter: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "engine", check_engine(self.engine))
        if isinstance(self.n_grid, bool) or not isinstance(self.n_grid, int) or self.n_grid < 1:
            raise DataError(f"n_grid must be an integer >= 1, got {self.n_grid!r}")
        opts = self.ipopt_options
        if opts is None:
            opts = ()
        if isinstance(opts, Mapping):
            opts = tuple(sorted(opts.items()))
        try:
            opts = tuple(sorted((str(k), v) for k, v in opts))
        except (TypeError, ValueError):
            raise DataError(
                f"ipopt_options must be a dict of option names to values, got {self.ipopt_options!r}"
            ) from None
        object.__setattr__(self, "ipopt_options", opts)
        if self.max_iter is not None and (
            isinstance(self.max_iter, bool) or not isinstance(self.max_iter, int) or self.max_iter < 1
        ):
            raise DataError(f"max_iter must be an integer >= 1, got {self.max_iter!r}")

    @property
    def ipopt_dict(self) -> dict | None:
        """``ipopt_options`` as a dict (``None`` when empty)."""
        return dict(self.ipopt_options) or None

    @classmethod
    def resolve(cls, settings: "FitSettings | None" = None, **overrides: Any) -> "FitSettings":
        """``settings`` (default ``FitSettings()``) with the given fields replaced (``None`` = keep)."""
        if settings is None and len(overrides) == 1 and isinstance(overrides.get("engine", 0), (str, type(None))):
            e = overrides["engine"]
            return _engine_only(DEFAULT_ENGINE if e is None else e)  # the common case, validated once
        if settings is not None and not isinstance(settings, FitSettings):
            raise DataError(f"settings must be a FitSettings, got {type(settings).__name__}")
        unknown = sorted(set(overrides) - set(SETTING_NAMES))
        if unknown:
            raise DataError(f"unknown setting(s) {unknown}; FitSettings has {list(SETTING_NAMES)}")
        given = {k: v for k, v in overrides.items() if v is not None}
        if (
            settings is None and set(given) <= {"engine"} and isinstance(given.get("engine", ""), str)
        ):  # the common case: cached, validated once
            return _engine_only(given.get("engine", DEFAULT_ENGINE))
        base = settings if settings is not None else cls()
        return replace(base, **given) if given else base


@lru_cache(maxsize=None)
def _engine_only(engine: str) -> FitSettings:
    return FitSettings(engine=engine)


#: Field names of :class:`FitSettings` (the keywords ``fit`` and ``fit_many`` take for them).
SETTING_NAMES = tuple(f.name for f in fields(FitSettings))
