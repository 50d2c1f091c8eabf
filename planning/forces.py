"""The forces a plan weighs: the soil's thrust at a slip, and the itemised motion resistance.

Both are evaluated from the model core (:func:`soiltrack.soilmodel.thrust_function`, Eq. 2;
:func:`soiltrack.soilmodel.effects.motion_resistance` and the Bekker compaction resistance of
:mod:`soiltrack.soilmodel.sinkage`), vectorised over soils and grades; no second copy of the
physics.
"""

from __future__ import annotations

import numpy as np

from ..soilmodel import Soil, Vehicle, thrust_function
from ..soilmodel.effects import effective_normal_load, motion_resistance
from ..soilmodel.thrust_effects import thrust_with_effects_function
from ..soilmodel.sinkage import compaction_resistance, has_bekker

__all__ = ["soil_thrust", "resistances"]


def resistances(
    vehicle: Vehicle,
    soil_bekker: Soil | None,
    theta: np.ndarray,
    accel: float,
    drawbar: float,
    *,
    effects: dict | None = None,
    slip: float = 0.0,
    speed: float = 0.0,
) -> tuple[np.ndarray, dict]:
    """Normal load and itemised required thrust at grades ``theta``.

    Parameters
    ----------
    vehicle
        The vehicle.
    soil_bekker
        A soil with Bekker parameters (compaction resistance), or ``None``/a soil without them.
    theta
        Grades, rad (array).
    accel, drawbar
        Acceleration to sustain (m/s^2) and drawbar pull (N).
    effects, slip, speed
        Fitted resistance effects ``{effect: {parameter: value}}`` (``slip_sinkage``,
        ``speed_resistance``), evaluated at ``|slip|`` and ``speed`` by
        :func:`~soiltrack.soilmodel.effects.motion_resistance`; adds the item ``"effects_N"``.

    Returns
    -------
    tuple
        ``(N, items)``: normal loads (N, array) and ``{"rolling_N", "compaction_N", "grade_N",
        "inertia_N", "drawbar_N"}`` (arrays like ``theta``; and ``"effects_N"`` when ``effects``).
    """
    W = vehicle.weight
    N = np.array([float(effective_normal_load(W, vehicle, {"grade": float(t)})) for t in np.atleast_1d(theta)])
    total_res = np.array(
        [
            float(motion_resistance(1.0, 0.0, vehicle, {"grade": float(t)}, standstill_speed=None))
            for t in np.atleast_1d(theta)
        ]
    )
    rolling = vehicle.rolling_resistance * N
    grade = total_res - rolling
    comp = (
        np.asarray(compaction_resistance(soil_bekker, vehicle, N), dtype=float)
        if soil_bekker is not None and has_bekker(soil_bekker)
        else np.zeros_like(N)
    )
    inertia = vehicle.mass * accel
    items = {
        "rolling_N": rolling,
        "compaction_N": comp,
        "grade_N": grade,
        "inertia_N": np.full_like(N, inertia),
        "drawbar_N": np.full_like(N, drawbar),
    }
    if effects is not None:
        items["effects_N"] = np.array(
            [
                float(motion_resistance(speed, slip, vehicle, {**effects, "grade": float(t)}, None, None, None))
                - float(motion_resistance(speed, slip, vehicle, {"grade": float(t)}, None, None, None))
                for t in np.atleast_1d(theta)
            ]
        )
    return N, items


def soil_thrust(
    thetas: np.ndarray, slip: float, N: np.ndarray | float, vehicle: Vehicle, model: str, *, effects: dict | None = None
) -> np.ndarray:
    """Soil thrust (N) at ``slip`` for soils ``thetas`` (rows c, phi, K in SI) and loads ``N`` (broadcast).

    Parameters
    ----------
    thetas
        One soil ``[c, phi, K]`` or rows of them.
    slip
        The slip.
    N
        Normal load(s), N.
    vehicle
        The vehicle (track length and width).
    model
        ``"full"`` or ``"cohesion-free"``.
    effects
        Fitted shear-law effects ``{effect: {parameter: value}}`` (``hump_shear``,
        ``pressure_distribution``): the thrust of
        :func:`~soiltrack.soilmodel.thrust_effects.thrust_with_effects_function` instead of Eq. 2.

    Returns
    -------
    numpy.ndarray
        One thrust per soil (or per load).
    """
    thetas = np.atleast_2d(thetas)
    n = max(thetas.shape[0], np.size(N))
    th = np.broadcast_to(thetas, (n, 3))
    NN = (
        np.broadcast_to(np.asarray(N, dtype=float).ravel(), (n,))
        if np.size(N) > 1
        else np.full(n, float(np.ravel(N)[0]))
    )
    args = [np.full((1, n), slip), th[:, 0].reshape(1, -1), th[:, 1].reshape(1, -1), th[:, 2].reshape(1, -1)]
    if effects:  # W is the nominal load of thrust_with_effects: with shear effects only, it is N itself
        out = thrust_with_effects_function(vehicle, effects, model)(*args, NN.reshape(1, -1))
    else:
        out = thrust_function(model)(*args, NN.reshape(1, -1), vehicle.track_length, vehicle.track_width)
    return np.asarray(out, dtype=float).ravel()
