"""The fit record's fields, and what the record's view mixins read from it.

:class:`~soiltrack.identify.estimates.result.FitResult` is assembled from three mixins
(:mod:`.views`, :mod:`.identifiability`, :mod:`.report`) that read the record's fields and each
other's properties. :class:`RecordFields`, their common base, is the frozen dataclass of the fields
(``FitResult`` inherits them, in this order), and declares under ``TYPE_CHECKING`` only the statistics
and views the mixins read from each other (the record's properties are their definitions).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

    from ...soilmodel.soil import Soil, SoilBounds
    from ...soilmodel.vehicle import Vehicle
    from .records import Combination, ParameterEstimate

__all__ = ["RecordFields"]


@dataclass(frozen=True, eq=False)
class RecordFields:
    """The fit record's fields (their one home) and, for the type checker, what its view mixins read."""

    data_kind: str
    model: str
    method: str
    theta: np.ndarray
    jacobian: np.ndarray
    weighted_residuals: np.ndarray
    residuals: np.ndarray
    residual_unit: str
    n_samples: int
    normal_loads: np.ndarray
    vehicle: Vehicle
    bounds: SoilBounds
    status: str
    success: bool
    message: str
    iterations: int
    solve_time: float
    sigma_known: bool
    rmse: float
    free: tuple[int, ...]
    #: ``(batched core statistics dict, index of this fit)`` when built in a batch, else None:
    #: computed from ``jacobian`` and ``weighted_residuals`` on first use (:attr:`_stats`).
    _core: Any = field(default=None, repr=False)
    _finite: bool = field(default=True, repr=False)  # theta, residuals (and effects) finite
    input_warnings: tuple[str, ...] = ()
    extra: dict = field(default_factory=dict)
    effect_labels: tuple[str, ...] = ()
    effect_values: Any = None
    effect_bounds: tuple = ()
    effect_units: tuple = ()
    effect_structure: Any = None
    fixed_labels: tuple[str, ...] = ()
    measured: str | None = None
    residual_model: Any = None
    #: ``{label: ReplacedInterval}`` replacing the linearised 95 % intervals of those parameters: profile
    #: likelihood (:mod:`soiltrack.identify.estimates.joint_likelihood`) or widened over both torque holds
    #: (:mod:`soiltrack.identify.drivelog.torque_hold`); None when every interval is the linearised one.
    replaced_intervals: Any = None

    if TYPE_CHECKING:
        # the record's statistics (result.FitResult)
        @property
        def rank(self) -> int: ...
        @property
        def dof(self) -> int: ...
        @property
        def cost(self) -> float: ...
        @property
        def s2(self) -> float | None: ...
        @property
        def scaled_singular_values(self) -> np.ndarray: ...
        @property
        def _V(self) -> np.ndarray: ...
        @property
        def _D(self) -> np.ndarray: ...
        @property
        def _Dok(self) -> np.ndarray: ...
        @property
        def _Pinv(self) -> np.ndarray: ...
        @property
        def _nonnull(self) -> np.ndarray: ...
        @property
        def parameter_names(self) -> tuple[str, ...]: ...
        @property
        def _n_all(self) -> int: ...
        @property
        def quantile(self) -> float | None: ...
        def _full(self, g) -> np.ndarray: ...
        def _effective_load(self, W: float) -> tuple[float, np.ndarray]: ...
        def _fmax(self, W: float) -> tuple[float, np.ndarray]: ...

        # views.EstimateViews
        @property
        def parameters(self) -> dict[str, ParameterEstimate]: ...
        @property
        def effects(self) -> dict[str, dict[str, ParameterEstimate]]: ...
        @property
        def combinations(self) -> list[Combination]: ...
        @property
        def soil(self) -> Soil | None: ...
        @property
        def ridge_point(self) -> Soil | None: ...
        @property
        def active_bounds(self) -> dict[str, str]: ...
        @property
        def outside_bounds(self) -> dict[str, str]: ...

        # identifiability.IdentifiabilityViews
        @property
        def identifiability(self) -> dict[str, Any]: ...
        @property
        def covariance(self) -> np.ndarray | None: ...
        @property
        def _identifiable_free(self) -> np.ndarray: ...
        @property
        def _cov_free(self) -> np.ndarray | None: ...
        @property
        def _cphi_ridge(self) -> bool: ...
        def _vif(self, g_scaled: np.ndarray) -> float: ...
        def _partner(self, k: int, identifiable: bool) -> tuple[str | None, float | None]: ...
        def _ridge_intervals(self, fmax: Combination) -> tuple[tuple, tuple, str]: ...

        # report.ReportViews
        @property
        def determined(self) -> tuple[str, ...]: ...
