"""What the record's view mixins read from the record, declared for the type checker.

:class:`~soiltrack.identify.estimates.result.FitResult` is assembled from three mixins
(:mod:`.views`, :mod:`.identifiability`, :mod:`.report`) that read the record's fields and each
other's properties. :class:`RecordFields`, their common base, declares those names under
``TYPE_CHECKING`` only: at run time it is an empty class (no field, no attribute, no cost); the
record's own dataclass fields and properties are the definitions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

    from ...soilmodel.soil import Soil, SoilBounds
    from ...soilmodel.vehicle import Vehicle
    from .records import Combination, ParameterEstimate

__all__ = ["RecordFields"]


class RecordFields:
    """Names the view mixins of the fit record read (type declarations only; see the module text)."""

    if TYPE_CHECKING:
        # the record's dataclass fields (result.FitResult)
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
        input_warnings: tuple[str, ...]
        extra: dict
        effect_labels: tuple[str, ...]
        effect_values: Any
        effect_bounds: tuple
        effect_units: tuple
        effect_structure: Any
        fixed_labels: tuple[str, ...]
        measured: str | None
        residual_model: Any
        replaced_intervals: Any

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
