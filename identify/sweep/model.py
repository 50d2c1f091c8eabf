"""The slip-sweep observation model, with effects: predictions, Jacobians and held-out residuals.

What a rig reports at apparent slip ``i`` and nominal load ``W`` is
:func:`soiltrack.soilmodel.effects.sweep_measurement` (tractive force or drawbar pull, the
effects' thrust and resistance terms, radius error on the slip). This module only wraps it
as one cached CasADi ``Function`` of ``(i, W, x)`` with ``x = [c, phi, K, e...]`` (``e``: the
identifiable effect parameters, order of :func:`~soiltrack.soilmodel.effects.effect_symbols`)
and its AD Jacobian, mapped over the samples. No physics is written here.
"""

from __future__ import annotations

from dataclasses import dataclass
import casadi as ca
import numpy as np

from ...soilmodel.data import SlipData
from ...soilmodel.effects import DEFAULT_RIG_SPEED, EffectSet, effect_structure, effect_symbols, sweep_measurement
from ...soilmodel.errors import DataError
from ...soilmodel.ridge import LOAD_RTOL
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.vehicle import Vehicle
from ..estimates.records import fit_vector, solver_converged

__all__ = ["observation_function", "predict", "slip_slope", "fit_vector", "nominal_offset", "SweepResiduals"]


@locked_cache(maxsize=128)
def _observation(vehicle: Vehicle, structure: EffectSet, model: str, measured: str, rig_speed: float) -> ca.Function:
    mapping, e, _ = effect_symbols(structure, ca.SX, vehicle)
    i, W = ca.SX.sym("i"), ca.SX.sym("W")
    th = ca.SX.sym("theta", 3)
    x = ca.vertcat(th, e)
    _, _, y = sweep_measurement(i, W, th[0], th[1], th[2], vehicle, mapping, model, measured, rig_speed)
    return ca.Function("sweep_observation", [i, W, x], [y, ca.jacobian(y, x)], ["i", "W", "x"], ["y", "dy_dx"])


def observation_function(
    vehicle: Vehicle,
    effects=None,
    model: str = "full",
    measured: str = "tractive_force",
    rig_speed: float = DEFAULT_RIG_SPEED,
) -> ca.Function:
    """Cached ``Function (i, W, x) -> (y, dy/dx)`` for one sample; ``x = [c, phi, K, e...]`` (SI)."""
    return _observation(vehicle, effect_structure(effects, vehicle), model, measured, float(rig_speed))


@locked_cache(maxsize=256)
def _mapped(vehicle: Vehicle, structure: EffectSet, model: str, measured: str, rig_speed: float, n: int) -> ca.Function:
    return _observation(vehicle, structure, model, measured, rig_speed).map(n)


def predict(
    x,
    slip,
    W,
    vehicle: Vehicle,
    effects=None,
    model: str = "full",
    measured: str = "tractive_force",
    rig_speed: float = DEFAULT_RIG_SPEED,
) -> tuple[np.ndarray, np.ndarray]:
    """Reported quantity (N) and its Jacobian ``(n, 3 + m)`` at ``x`` for samples ``(slip, W)``."""
    s = np.asarray(slip, dtype=float).reshape(1, -1)
    n = s.shape[1]
    structure = effect_structure(effects, vehicle) if effects else EffectSet()
    Wr = np.broadcast_to(np.asarray(W, dtype=float), (n,)).reshape(1, -1)
    x = np.asarray(x, dtype=float).reshape(-1, 1)
    y, J = _mapped(vehicle, structure, model, measured, float(rig_speed), n)(s, Wr, x)
    return np.asarray(y, dtype=float).ravel(), np.asarray(J, dtype=float).reshape(n, x.size)


@locked_cache(maxsize=64)
def _slope_mapped(
    vehicle: Vehicle, structure: EffectSet, model: str, measured: str, rig_speed: float, n: int
) -> ca.Function:
    obs = _observation(vehicle, structure, model, measured, rig_speed)  # the one observation model
    i, W = ca.SX.sym("i"), ca.SX.sym("W")
    x = ca.SX.sym("x", obs.size1_in(2))
    y = obs(i, W, x)[0]
    return ca.Function("sweep_slope", [i, W, x], [ca.jacobian(y, i)], ["i", "W", "x"], ["dy_di"]).map(n)


def slip_slope(
    x,
    slip,
    W,
    vehicle: Vehicle,
    effects=None,
    model: str = "full",
    measured: str = "tractive_force",
    rig_speed: float = DEFAULT_RIG_SPEED,
) -> np.ndarray:
    """Slope ``dy/di`` (N per unit slip) of the reported quantity at each sample, by AD of the same model.

    What a slip error ``delta i`` does to a sample: ``y(i + delta i) ~ y(i) + dy/di delta i``
    (:mod:`soiltrack.identify.sweep.slip_noise` weights samples with it).
    """
    s = np.asarray(slip, dtype=float).reshape(1, -1)
    n = s.shape[1]
    structure = effect_structure(effects, vehicle) if effects else EffectSet()
    Wr = np.broadcast_to(np.asarray(W, dtype=float), (n,)).reshape(1, -1)
    f = _slope_mapped(vehicle, structure, model, measured, float(rig_speed), n)
    return np.asarray(f(s, Wr, np.asarray(x, dtype=float).reshape(-1, 1)), dtype=float).ravel()


def nominal_offset(slip, W, vehicle: Vehicle, rig_speed: float = DEFAULT_RIG_SPEED) -> np.ndarray:
    """Nominal motion resistance the rig adds to a drawbar pull to report tractive force, N.

    ``tractive force - drawbar pull`` of the nominal model (``W mu_r`` while the carriage moves);
    adding it to drawbar-pull data turns them into the equivalent tractive-force data (the
    residuals are identical), which is how fits without effects take drawbar pull.
    """
    x = np.zeros(3)
    x[1], x[2] = 0.5, 0.01  # any soil: the difference does not depend on it
    tf, _ = predict(x, slip, W, vehicle, None, "full", "tractive_force", rig_speed)
    dp, _ = predict(x, slip, W, vehicle, None, "full", "drawbar_pull", rig_speed)
    return tf - dp


@dataclass(frozen=True)
class SweepResiduals:
    """Held-out residuals of a slip-sweep fit (the :attr:`FitResult.residual_model` of slip fits).

    Parameters
    ----------
    rig_speed
        Track speed of the rig the fit assumed, m/s.
    """

    rig_speed: float = DEFAULT_RIG_SPEED

    def residuals_on(self, result, data, accept_implausible: bool = False) -> dict[str, np.ndarray]:
        """``{channel: measured - predicted}`` (N) of ``result``'s model on the slip data ``data``.

        A fit that did not succeed predicts nothing and is refused (:class:`DataError`), except,
        with ``accept_implausible=True``, one whose solver converged and only the plausibility
        checks flagged (the diagnosis: a nominal model missing an effect is implausible by design).
        """
        if not isinstance(data, SlipData):
            raise DataError(
                f"residuals_on: the fit is on slip data; got {type(data).__name__}", file=getattr(data, "source", None)
            )
        if not (result.success or (accept_implausible and solver_converged(result))):
            raise DataError(
                f"residuals_on: the fit did not succeed ({result.status}); it predicts nothing", file=data.source
            )
        W = data.loads(result.vehicle.weight).astype(float)
        if result.model == "full" and len(result.normal_loads) == 1 and result.soil is None:
            W0 = float(result.normal_loads[0])
            bad = np.nonzero(np.abs(W - W0) > LOAD_RTOL * W0)[0]
            if bad.size:
                raise DataError(
                    f"the fit saw one normal load ({W0:.6g} N), where c and phi are not separable: its "
                    f"prediction at {W[bad[0]]:.6g} N is not determined",
                    file=data.source,
                    column="normal_load_N",
                    row=int(bad[0]) + 1,
                )
        x = fit_vector(result)
        effects = result.effect_structure if result.effect_labels else None
        y, _ = predict(x, data.slip, W, result.vehicle, effects, result.model, data.measured, self.rig_speed)
        return {data.channel: data.values - y}
