"""What a bevameter test fit returns: its parameters with intervals, what they identify, the solver's word."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from ..estimates.records import ParameterEstimate
from ..outcome import Outcome, decide_outcome, outcome_lines, running_gear_json

__all__ = ["TestCombination", "SoilTestFit", "SOIL_TEST_KINDS"]

#: The bevameter test kinds: shear ring/box (c, phi, K), plate sinkage (k_c, k_phi, n).
SOIL_TEST_KINDS = ("shear_test", "plate_test")


_LEVEL_LABELS = {"normal_pressures_kpa": "normal pressures (kPa)", "plate_widths_m": "plate widths (m)"}


def _f(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class TestCombination:
    """An identifiable combination when the parameters themselves are not (one pressure, one plate).

    Attributes
    ----------
    key, expression, unit
        JSON name, formula and unit (e.g. ``bekker_k_eq``, ``k_c / b + k_phi``, ``kN/m^(n+2)``).
    value, stderr, ci95
        Estimate, standard error and 95 % interval.
    at
        The condition it holds at, e.g. ``{"plate_width_m": 0.1}``.
    """

    key: str
    expression: str
    unit: str
    value: float | None
    stderr: float | None
    ci95: tuple[float | None, float | None]
    at: dict

    def to_dict(self) -> dict:
        """JSON-ready dict; never NaN."""
        return {
            "name": self.key,
            "expression": self.expression,
            "unit": self.unit,
            "value": _f(self.value),
            "stderr": _f(self.stderr),
            "ci95": [_f(self.ci95[0]), _f(self.ci95[1])],
            "identifiable": True,
            **{k: _f(v) for k, v in self.at.items()},
        }


@dataclass(frozen=True)
class SoilTestFit:
    """A fitted bevameter test.

    Attributes
    ----------
    kind
        ``"shear_test"`` or ``"plate_test"``.
    source
        The file (or label) fitted.
    parameters
        ``{JSON key: ParameterEstimate}`` (SI inside; edge units in the JSON and report) in the JSON order.
    combinations
        ``{key: TestCombination}``: what one pressure / one plate width identifies.
    converged, status, iterations, solve_time_s
        The solver's word (IPOPT), never hidden.
    n_samples, rmse, rmse_unit
        Rows fitted and the rms misfit (in ``rmse_unit``).
    levels
        The test's conditions, e.g. ``{"normal_pressures_kpa": [...]}`` or ``{"plate_widths_m": [...]}``.
    notes
        Plain-words statements (identifiability, bounds).
    covariance_si
        Covariance of the identifiable parameters in SI (``[c, phi, K]`` or ``[k_c, k_phi, n]``),
        for propagating into predictions; ``None`` when not all three are identifiable.
    values_si
        The same parameters' values in SI (``None`` when not identifiable).
    """

    kind: str
    source: str
    parameters: dict[str, ParameterEstimate]
    combinations: dict
    converged: bool
    status: str
    iterations: int
    solve_time_s: float
    n_samples: int
    rmse: float
    rmse_unit: str
    levels: dict
    notes: tuple[str, ...] = ()
    covariance_si: np.ndarray | None = field(default=None, repr=False)
    values_si: tuple[float | None, ...] = ()

    @property
    def success(self) -> bool:
        """IPOPT converged, the data identify at least one parameter, and every reported number is finite."""
        vals = [p.value for p in self.parameters.values() if p.identifiable]
        return bool(self.converged and vals and all(v is not None and math.isfinite(v) for v in vals))

    @property
    def determined(self) -> list[str]:
        """What the data determine: identified parameters and combinations with a whole interval."""
        out = [k for k, p in self.parameters.items() if p.identified[0]]
        out += [k for k, c in self.combinations.items() if c.stderr is not None and None not in tuple(c.ci95)]
        return out

    @property
    def fit_outcome(self) -> Outcome:
        """The fit's outcome by the one set of rules (:mod:`soiltrack.identify.outcome`)."""
        vals = [p.value for p in self.parameters.values() if p.identifiable]
        finite = all(v is not None and math.isfinite(v) for v in vals)
        return decide_outcome(
            solver_ok=bool(self.converged and finite),
            failure=f"IPOPT {self.status}" if not self.converged else "non-finite numbers",
            determined=self.determined,
        )

    @property
    def outcome(self) -> str:
        """One of :data:`~soiltrack.identify.outcome.OUTCOMES`."""
        return self.fit_outcome.outcome

    @property
    def running_gear(self) -> dict:
        """The JSON ``running_gear``: a bevameter (the soil itself was measured; no weight)."""
        return running_gear_json("bevameter", name=self.kind.replace("_", " "))

    @property
    def active_bounds(self) -> list[str]:
        """Keys of the parameters that end on a bound."""
        return [k for k, p in self.parameters.items() if p.at_bound]

    @property
    def identifiable(self) -> list[str]:
        """Keys of the parameters the data identify."""
        return [k for k, p in self.parameters.items() if p.identifiable]

    def to_dict(self) -> dict:
        """JSON-ready dict (the ``soiltrack fit --json`` object of a bevameter file); never NaN."""
        return {
            "kind": self.kind,
            "source": self.source,
            "method": "ipopt",
            "status": self.status,
            "success": self.success,
            **self.fit_outcome.to_dict(),
            "running_gear": self.running_gear,
            "converged": bool(self.converged),
            "iterations": int(self.iterations),
            "n_samples": int(self.n_samples),
            f"rmse_{self.rmse_unit}": _f(self.rmse),
            "solve_time_s": _f(self.solve_time_s),
            "levels": self.levels,
            "parameters": {k: p.to_dict() for k, p in self.parameters.items()},
            "combinations": [c.to_dict() for c in self.combinations.values()],
            "identifiable": self.identifiable,
            "active_bounds": self.active_bounds,
            "notes": list(self.notes),
            "covariance": self._covariance_dict(),
        }

    def _covariance_dict(self) -> dict | None:
        """``{"parameters", "values", "matrix", "units": "SI"}`` of the identified parameters, or ``None``."""
        if self.covariance_si is None or any(v is None for v in self.values_si):
            return None
        names = (
            ["cohesion", "friction_angle", "shear_modulus"]
            if self.kind == "shear_test"
            else ["bekker_kc", "bekker_kphi", "bekker_n"]
        )
        C = np.asarray(self.covariance_si, dtype=float)
        if not np.all(np.isfinite(C)):
            return None
        return {
            "parameters": names,
            "values": [float(cast(float, v)) for v in self.values_si],  # none is None (checked above)
            "matrix": [[float(x) for x in row] for row in C],
            "units": "SI",
        }

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON text."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def report(self) -> str:
        """Plain-text report: the solver's word, each parameter with its interval, what is not identifiable."""
        title = "bevameter shear test" if self.kind == "shear_test" else "plate sinkage test"
        lvl = "; ".join(
            f"{_LEVEL_LABELS.get(k, k)}: {', '.join(f'{v:.4g}' for v in vals)}" for k, vals in self.levels.items()
        )
        nid = [p.words for p in self.parameters.values() if not p.identified[0]]
        lines = outcome_lines(self.fit_outcome, determined=self.determined, not_identified=nid) + [
            f"{title}: {self.source} ({self.n_samples} rows; {lvl})",
            f"solver: IPOPT {'converged' if self.converged else 'DID NOT CONVERGE'} ({self.status}), "
            f"{self.iterations} iterations, {self.solve_time_s:.3f} s; rms misfit {self.rmse:.4g} "
            f"{self.rmse_unit}",
        ]
        for p in self.parameters.values():
            if not p.identifiable:
                lines.append(f"  {p.words:<28} not identifiable (see the note)")
                continue
            lo, hi = p.edge_ci95
            ci = f"[{lo:.4g}, {hi:.4g}]" if lo is not None and hi is not None else "[n/a]"
            ok, why = p.identified
            flag = "  ON A BOUND (not identified; interval not reliable)" if p.at_bound else ""
            flag += "" if ok or p.at_bound else f"  NOT IDENTIFIED ({why})"
            lines.append(f"  {p.words:<28} {p.edge_value:>10.4g} {p.edge_unit:<12} 95 % {ci}{flag}")
        for c in self.combinations.values():
            at = ", ".join(f"{k} = {v:.4g}" for k, v in c.at.items())
            ci = f"[{c.ci95[0]:.4g}, {c.ci95[1]:.4g}]" if None not in c.ci95 else "[n/a]"
            lines.append(f"  {c.expression + ' (' + at + ')':<40} {c.value:.4g} {c.unit}  95 % {ci}")
        lines += [f"note: {n}" for n in self.notes]
        o = self.fit_outcome
        lines.append("result: " + ("usable" if o.usable else f"{o.outcome.upper()} ({o.reason})"))
        return "\n".join(lines)
