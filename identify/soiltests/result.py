"""What a bevameter test fit returns: the library's one record (:class:`~..estimates.estimate.Estimate`).

Its parameters are :class:`~..estimates.records.ParameterEstimate`, what one pressure or one plate width
identifies a :class:`~..estimates.records.Combination`; report and JSON are the record's free functions
(:func:`~..estimates.estimate.estimate_report`, :func:`~..estimates.estimate.estimate_dict`).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..estimates.estimate import CovarianceBlock, DataProvenance, Estimate, ResidualChannel, SolverRun
from ..estimates.records import Combination, ParameterEstimate
from ..outcome import running_gear_json
from .lsq import LsqSolution

__all__ = ["SoilTestFit", "SOIL_TEST_KINDS", "soil_test_estimate", "one_level_combination"]

#: The bevameter test kinds: shear ring/box (c, phi, K), plate sinkage (k_c, k_phi, n).
SOIL_TEST_KINDS = ("shear_test", "plate_test")

#: A bevameter test's fit is the one record (the name kept for the callers of earlier versions).
SoilTestFit = Estimate

_TITLES = {"shear_test": "bevameter shear test", "plate_test": "plate sinkage test"}
_LEVEL_LABELS = {"normal_pressures_kpa": "normal pressures (kPa)", "plate_widths_m": "plate widths (m)"}
_CHANNELS = {"shear_test": "shear_stress", "plate_test": "pressure"}
_COVARIANCE_NAMES = {
    "shear_test": ("cohesion", "friction_angle", "shear_modulus"),
    "plate_test": ("bekker_kc", "bekker_kphi", "bekker_n"),
}


def one_level_combination(key: str, expression: str, description: str, par: ParameterEstimate, at: dict) -> Combination:
    """The combination one pressure or one plate width identifies, from its fitted record (edge units)."""
    return Combination(
        key,
        par.edge_value,  # type: ignore[arg-type]  # an identified combination has a value
        par.edge_stderr,
        par.edge_ci95,
        par.edge_unit,
        description,
        estimable=par.identifiable,
        expression=expression,
        at=dict(at),
    )


def soil_test_estimate(
    *,
    kind: str,
    source: str,
    params: Sequence[ParameterEstimate],
    combos: dict[str, Combination],
    sol: LsqSolution,
    n_samples: int,
    residuals_kpa: np.ndarray,
    levels: dict,
    notes: Sequence[str],
    covariance_si: np.ndarray | None,
    values_si: tuple,
) -> Estimate:
    """The record of a bevameter fit (``kind`` of :data:`SOIL_TEST_KINDS`).

    ``residuals_kpa``: measured minus model per row, kPa; ``covariance_si`` / ``values_si``: of the three
    parameters (``None`` / with ``None`` when not all are identifiable: no covariance block).
    """
    table = {p.key: p for p in params}
    vals = [p.value for p in params if p.identifiable]
    finite = all(v is not None and math.isfinite(v) for v in vals)
    cov = None
    if covariance_si is not None and all(v is not None for v in values_si):
        cov = CovarianceBlock(_COVARIANCE_NAMES[kind], tuple(float(v) for v in values_si), np.array(covariance_si))
    return Estimate(
        kind=kind,
        parameters=table,
        combinations=combos,
        solver=SolverRun(
            "ipopt",
            bool(sol.converged),
            str(sol.status),
            finite=finite,
            iterations=int(sol.iterations),
            solve_time_s=float(sol.solve_time_s),
            starts=int(sol.starts),
        ),
        data=DataProvenance(
            source=source,
            title=_TITLES[kind],
            n_samples=int(n_samples),
            running_gear=running_gear_json("bevameter", name=kind.replace("_", " ")),
            conditions=levels,
            condition_labels=_LEVEL_LABELS,
        ),
        residuals=(ResidualChannel(_CHANNELS[kind], "kPa", np.array(residuals_kpa, dtype=float)),),
        covariance=cov,
        dof=int(n_samples) - int(np.asarray(sol.x).size),
        notes=tuple(notes),
    )
