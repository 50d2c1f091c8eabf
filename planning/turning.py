"""Can it turn here: a steady turn of given radius and speed with the steering model.

:func:`turn_margin` solves the steady motion at forward speed ``u = S`` and yaw rate
``Om = S / R`` (the path radius is ``sqrt(u^2 + v^2) / Om``, within the sideslip's cosine of R;
the sideslip is reported) with :func:`~soiltrack.soilmodel.steering.motion_inverse_function`,
and checks three limits:

- ``soil``: the soil holds the turn (the balances have a solution with both sprockets turning
  forwards and both tracks loaded), the sideslip is at most :data:`MAX_SIDESLIP_DEG` (else the
  vehicle slides out of its path) and the outer track's slip at most ``max_slip``;
- ``torque``: each sprocket's torque at most half the vehicle's ``max_sprocket_torque`` (which is
  of both tracks together; an equal split is assumed);
- ``power``: the sum of the driving sprockets' powers ``T_k w_k > 0`` at most ``max_power`` (the
  inner track's braking power is not recovered: a conservative assumption).

The smallest turning radius at the speed is found by bisection on ``log |R|`` between half the
tread and :data:`R_MAX`. Drivetrain limits the vehicle does not give are the simulator's
documented defaults (:func:`~soiltrack.soilmodel.simulation.drive_limits`), said in ``notes``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..soilmodel import DataError, Soil, Vehicle
from ..soilmodel.simulation import drive_limits
from ..soilmodel.steering import (
    SteeringSettings,
    hull_forces_function,
    motion_inverse_function,
    tread_of,
    vehicle_parameters,
)
from ..soilmodel.threadsafe import call_solver, locked_cache

__all__ = [
    "TurnMargin",
    "TurnProbability",
    "turn_margin",
    "turn_point",
    "turn_points",
    "turn_probability",
    "min_turn_radius",
    "R_MAX",
]

#: Largest radius searched for the smallest feasible one, m (beyond it a turn is straight driving).
R_MAX = 1e4
#: Largest sideslip of the centre (deg) at which the vehicle still follows its path; beyond it it slides out.
MAX_SIDESLIP_DEG = 10.0
#: Why ``p_turn_feasible`` is null (the JSON's ``p_turn_method``).
NO_UNCERTAINTY = "null: the soil is given without uncertainty (--terrain or --soil); --fit FIT.json gives a probability"
#: Bisection steps on log |R| (a relative resolution of about 2e-4 between half the tread and R_MAX).
BISECTION_STEPS = 40


#: Monte Carlo samples of the soil for ``p_turn_feasible`` (binomial standard error at most 0.5/sqrt(n) = 0.018).
DEFAULT_TURN_SAMPLES = 800


@dataclass(frozen=True)
class TurnProbability:
    """``p_turn_feasible`` from the soil's uncertainty (Monte Carlo over the fit's Gaussian).

    Attributes
    ----------
    p
        Fraction of the sampled soils on which the turn is feasible (all limits of :func:`turn_margin`).
    stderr
        Its binomial standard error ``sqrt(p (1 - p) / n)``.
    n_samples, seed
        Samples drawn and the generator's seed (reproducible).
    limited_by
        Fraction of the samples on which each limit binds (``soil``, ``torque``, ``power``).
    method
        How the probability was obtained, in words.
    """

    p: float
    stderr: float
    n_samples: int
    seed: int
    limited_by: dict
    method: str

    def to_dict(self) -> dict:
        """The keys ``margin --json`` adds beside ``p_turn_feasible``."""
        return {
            "p_turn_feasible": self.p,
            "p_turn_feasible_se": self.stderr,
            "p_turn_samples": self.n_samples,
            "p_turn_limited_by": self.limited_by,
            "p_turn_method": self.method,
        }


@dataclass(frozen=True)
class TurnMargin:
    """The turn's torques, slips and limits (JSON keys of DESIGN section 9 in :meth:`to_dict`)."""

    radius_m: float
    speed_m_s: float
    solved: bool
    torque_left_Nm: float | None
    torque_right_Nm: float | None
    slip_outer: float | None
    slip_inner: float | None
    sideslip_deg: float | None
    power_W: float | None
    turn_feasible: bool
    turn_limited_by: str | None
    min_turn_radius_m: float | None
    torque_limit_Nm: float
    power_limit_W: float
    notes: tuple[str, ...] = ()
    probability: TurnProbability | None = None

    def to_dict(self) -> dict:
        """The keys ``margin --json`` adds with ``--turn-radius``."""
        return {
            "turn_radius_m": self.radius_m,
            "turn_speed_m_s": self.speed_m_s,
            "torque_left_Nm": self.torque_left_Nm,
            "torque_right_Nm": self.torque_right_Nm,
            "slip_outer": self.slip_outer,
            "slip_inner": self.slip_inner,
            "sideslip_deg": self.sideslip_deg,
            "turn_power_W": self.power_W,
            "min_turn_radius_m": self.min_turn_radius_m,
            "turn_feasible": self.turn_feasible,
            "turn_limited_by": self.turn_limited_by,
            "turn_torque_limit_per_track_Nm": self.torque_limit_Nm,
            "turn_power_limit_W": self.power_limit_W,
            "turn_notes": list(self.notes),
            **(
                self.probability.to_dict()
                if self.probability is not None
                else {"p_turn_feasible": None, "p_turn_method": NO_UNCERTAINTY}
            ),
        }

    def report(self) -> str:
        """A few lines for the margin report."""
        side = "left" if self.radius_m > 0 else "right"
        head = f"turn {abs(self.radius_m):g} m to the {side} at {self.speed_m_s:g} m/s: "
        tl, tr = self.torque_left_Nm, self.torque_right_Nm
        if not self.solved or tl is None or tr is None:
            body = "the soil cannot hold it (no steady motion)"
        else:
            body = (
                f"torques left {tl / 1e3:.3g} kN m, right {tr / 1e3:.3g} kN m; "
                f"slip outer {self.slip_outer:.3g}, inner {self.slip_inner:.3g}; sideslip {self.sideslip_deg:.2g} deg"
            )
        verdict = "feasible" if self.turn_feasible else f"NOT feasible (limited by {self.turn_limited_by})"
        rmin = "none" if self.min_turn_radius_m is None else f"{self.min_turn_radius_m:.3g} m"
        pr = self.probability
        prob = (
            f"  probability feasible {pr.p:.3g} (+- {pr.stderr:.2g}; {pr.n_samples} soils sampled from the fit)"
            if pr is not None
            else "  probability feasible: none (the soil is given without uncertainty)"
        )
        lines = [head + body, f"  {verdict}; smallest turning radius at this speed: {rmin}", prob]
        return "\n".join([*lines, *self.notes])


def turn_points(
    vehicle: Vehicle,
    soils: np.ndarray,
    radius_m: float,
    speed_m_s: float,
    settings: SteeringSettings = SteeringSettings(),
) -> tuple[np.ndarray, ...]:
    """``(solved, w_l, w_r, v, T_l, T_r)`` arrays of the steady turn on each row ``[c, phi, K]`` (SI) of ``soils``."""
    n = np.atleast_2d(soils).shape[0]
    u = np.full(n, float(speed_m_s))
    return motion_points(vehicle, soils, u, u / float(radius_m), np.zeros(n), np.zeros(n), settings)


def motion_points(
    vehicle: Vehicle,
    soils: np.ndarray,
    u: np.ndarray,
    yaw_rate: np.ndarray,
    du: np.ndarray,
    dyaw: np.ndarray,
    settings: SteeringSettings = SteeringSettings(),
) -> tuple[np.ndarray, ...]:
    """``(solved, w_l, w_r, v, T_l, T_r)`` arrays of a prescribed hull motion per column (u, Om, du/dt, dOm/dt).

    One mapped call of :func:`~soiltrack.soilmodel.steering.motion_inverse_function` for all
    points (built once per size); the balances are checked afterwards (scaled by W and W l, below
    1e-7) with both sprockets turning forwards and both tracks loaded (``solved``).
    """
    soils = np.atleast_2d(np.asarray(soils, dtype=float))
    n = soils.shape[0]
    u, Om, du, dOm = (np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in (u, yaw_rate, du, dyaw))
    veh = np.asarray(vehicle_parameters(vehicle), dtype=float)
    r, B, Iz = vehicle.sprocket_radius, tread_of(vehicle), veh[7]
    V = np.tile(veh[:, None], (1, n))
    P = np.vstack([u, Om, du, dOm, soils.T, V])
    z0 = np.vstack([(u - Om * B / 2) / (0.97 * r), (u + Om * B / 2) / (0.97 * r), np.zeros(n)])
    z, _ = call_solver(_mapped("motion", settings, n), z0, P)
    z = np.asarray(z, dtype=float).reshape(3, n)
    mo = np.vstack([u, z[2], Om])
    Fx, net, W = (
        np.asarray(a, dtype=float).reshape(-1, n) for a in _mapped("forces", settings, n)(mo, z[:2], soils.T, u * Om, V)
    )
    m, Wt = vehicle.mass, vehicle.weight
    err = np.vstack(
        [
            (net[0] - m * (du - z[2] * Om)) / Wt,
            (net[1] - m * u * Om) / Wt,
            (net[2] - Iz * dOm) / (Wt * vehicle.track_length),
        ]
    )
    with np.errstate(invalid="ignore"):
        solved = (
            np.all(np.isfinite(z), axis=0)
            & (np.max(np.abs(err), axis=0) < 1e-7)
            & np.all(z[:2] > 0, axis=0)
            & np.all(W > 0, axis=0)
        )
    return solved, z[0], z[1], z[2], r * Fx[0], r * Fx[1]


@locked_cache(maxsize=32)
def _mapped(kind: str, settings: SteeringSettings, n: int):
    """The motion rootfinder (``kind="motion"``) or the hull forces mapped over n soils (cached per size)."""
    f = motion_inverse_function(settings) if kind == "motion" else hull_forces_function(settings)
    return f.map(n)


def turn_point(
    vehicle: Vehicle, soil: Soil, radius_m: float, speed_m_s: float, settings: SteeringSettings = SteeringSettings()
):
    """``(solved, w_l, w_r, v, T_l, T_r)`` of the steady turn at radius R (+ left) and forward speed S."""
    sv = [[soil.cohesion, soil.friction_angle, soil.shear_modulus]]
    solved, wl, wr, v, Tl, Tr = turn_points(vehicle, np.asarray(sv), radius_m, speed_m_s, settings)
    return bool(solved[0]), wl[0], wr[0], v[0], Tl[0], Tr[0]


def classify_turn(vehicle, radius_m, speed_m_s, max_slip, limits, d):
    """``(limit or None, reason)`` of one solved-or-not turn ``d = (solved, w_l, w_r, v, T_l, T_r)``."""
    solved, wl, wr, v, Tl, Tr = d
    if not solved:
        if np.all(np.isfinite([wl, wr])) and min(wl, wr) <= 0:
            return "soil", "the inner sprocket would have to stop or reverse (a pivot turn: outside the model)"
        return "soil", "the soil cannot hold the turn (no steady motion)"
    r, B = vehicle.sprocket_radius, tread_of(vehicle)
    Om = speed_m_s / radius_m
    sl, sr = 1 - (speed_m_s - Om * B / 2) / (r * wl), 1 - (speed_m_s + Om * B / 2) / (r * wr)
    outer = sr if radius_m > 0 else sl
    beta = math.degrees(math.atan2(abs(v), speed_m_s))
    if beta > MAX_SIDESLIP_DEG:
        return "soil", f"the vehicle slides out of the turn (sideslip {beta:.3g} deg > {MAX_SIDESLIP_DEG:g})"
    if outer > max_slip:
        return "soil", f"the outer track's slip {outer:.3g} exceeds the allowed {max_slip:g}"
    if max(abs(Tl), abs(Tr)) > 0.5 * limits.max_sprocket_torque:
        return "torque", f"a sprocket torque exceeds {0.5 * limits.max_sprocket_torque:.4g} N m"
    if max(Tl * wl, 0.0) + max(Tr * wr, 0.0) > limits.max_power:
        return "power", f"the driving sprockets' power exceeds {limits.max_power:.4g} W"
    return None, None


def _check(vehicle, soil, radius_m, speed_m_s, max_slip, limits, settings):
    """``(limit or None, reason, details)`` of one turn: the first limit it breaks (soil, torque, power)."""
    d = turn_point(vehicle, soil, radius_m, speed_m_s, settings)
    return (*classify_turn(vehicle, radius_m, speed_m_s, max_slip, limits, d), d)


def min_turn_radius(vehicle, soil, speed_m_s, *, max_slip=0.2, settings=SteeringSettings()) -> float | None:
    """Smallest feasible |R| (m) at the speed, by bisection on log |R| (left turn; the model is symmetric)."""
    limits = drive_limits(vehicle)
    lo, hi = 0.5 * tread_of(vehicle) * (1 + 1e-6), R_MAX
    if _check(vehicle, soil, hi, speed_m_s, max_slip, limits, settings)[0] is not None:
        return None
    if _check(vehicle, soil, lo, speed_m_s, max_slip, limits, settings)[0] is None:
        return lo
    for _ in range(BISECTION_STEPS):
        mid = math.sqrt(lo * hi)
        if _check(vehicle, soil, mid, speed_m_s, max_slip, limits, settings)[0] is None:
            hi = mid
        else:
            lo = mid
    return hi


def turn_margin(
    vehicle: Vehicle,
    soil: Soil,
    *,
    radius_m: float,
    speed_m_s: float,
    max_slip: float = 0.2,
    uncertainty=None,
    n_samples: int | None = None,
    settings: SteeringSettings = SteeringSettings(),
) -> TurnMargin:
    """Can the vehicle turn at radius ``radius_m`` (signed, + left) and forward speed ``speed_m_s`` here.

    With ``uncertainty`` (a :class:`~.uncertainty.SoilUncertainty` whose mean soil is ``soil``) the
    result carries :func:`turn_probability` (``n_samples`` soils, default :data:`DEFAULT_TURN_SAMPLES`).

    Raises
    ------
    DataError
        No tread, a radius not beyond half the tread, a speed not > 0, a slip limit outside (0, 1).
    """
    vehicle_parameters(vehicle)  # tread checked
    B = tread_of(vehicle)
    if not (math.isfinite(radius_m) and abs(radius_m) > 0.5 * B):
        raise DataError(f"--turn-radius {radius_m:g} m must be larger than half the tread ({0.5 * B:g} m)")
    if not (math.isfinite(speed_m_s) and speed_m_s > 0):
        raise DataError(f"--speed must be > 0 m/s with --turn-radius, got {speed_m_s:g}")
    if not 0 < max_slip < 1:
        raise DataError(f"max_slip must lie in (0, 1), got {max_slip:g}")
    limits = drive_limits(vehicle)
    limit, reason, (solved, wl, wr, v, Tl, Tr) = _check(vehicle, soil, radius_m, speed_m_s, max_slip, limits, settings)
    notes = [reason] if reason else []
    if limits.torque_assumed or limits.power_assumed:
        notes.append("the vehicle gives no torque or power limit: the library's defaults are used (0.8 W r, 15 W/kg)")
    r = vehicle.sprocket_radius
    Om = speed_m_s / radius_m
    sl, sr = (
        (1 - (speed_m_s - Om * B / 2) / (r * wl), 1 - (speed_m_s + Om * B / 2) / (r * wr)) if solved else (None, None)
    )
    outer, inner = (sr, sl) if radius_m > 0 else (sl, sr)
    return TurnMargin(
        radius_m=float(radius_m),
        speed_m_s=float(speed_m_s),
        solved=solved,
        torque_left_Nm=float(Tl) if solved else None,
        torque_right_Nm=float(Tr) if solved else None,
        slip_outer=None if outer is None else float(outer),
        slip_inner=None if inner is None else float(inner),
        sideslip_deg=math.degrees(math.atan2(v, speed_m_s)) if solved else None,
        power_W=float(max(Tl * wl, 0.0) + max(Tr * wr, 0.0)) if solved else None,
        turn_feasible=limit is None,
        turn_limited_by=limit,
        min_turn_radius_m=min_turn_radius(vehicle, soil, speed_m_s, max_slip=max_slip, settings=settings),
        torque_limit_Nm=0.5 * limits.max_sprocket_torque,
        power_limit_W=limits.max_power,
        notes=tuple(notes),
        probability=None
        if uncertainty is None
        else turn_probability(
            vehicle,
            uncertainty,
            radius_m=radius_m,
            speed_m_s=speed_m_s,
            max_slip=max_slip,
            n_samples=n_samples or DEFAULT_TURN_SAMPLES,
            settings=settings,
        ),
    )


def turn_probability(
    vehicle: Vehicle,
    uncertainty,
    *,
    radius_m: float,
    speed_m_s: float,
    max_slip: float = 0.2,
    n_samples: int = DEFAULT_TURN_SAMPLES,
    seed: int = 0,
    settings: SteeringSettings = SteeringSettings(),
) -> TurnProbability:
    """Probability that the turn is feasible, over the soil's uncertainty (a :class:`~.uncertainty.SoilUncertainty`).

    Soils are drawn from the fit's Gaussian (clipped to its bounds; for a ridge fit the worst
    ridge point at the vehicle's weight, :meth:`~.uncertainty.SoilUncertainty.soils_at`), each
    turn solved by one mapped rootfinder call and checked against every limit. A linearisation of
    the binding limit's margin is not used: far outside the limit the turn has no steady motion,
    so the margin has no derivative there. With the same seed, the samples are the same at every
    radius (common random numbers), so the probability is monotone in the radius wherever each
    soil's own feasibility is.
    """
    if not (isinstance(n_samples, int) and n_samples >= 10):
        raise DataError(f"n_samples must be an integer >= 10, got {n_samples!r}")
    limits = drive_limits(vehicle)
    soils = uncertainty.soils_at(uncertainty.sample(n_samples, seed), vehicle.weight)
    cols = turn_points(vehicle, soils, radius_m, speed_m_s, settings)
    counts = {"soil": 0, "torque": 0, "power": 0}
    for k in range(n_samples):
        limit, _ = classify_turn(vehicle, radius_m, speed_m_s, max_slip, limits, tuple(c[k] for c in cols))
        if limit is not None:
            counts[limit] += 1
    p = 1.0 - sum(counts.values()) / n_samples
    return TurnProbability(
        p=float(p),
        stderr=float(math.sqrt(p * (1 - p) / n_samples)),
        n_samples=n_samples,
        seed=seed,
        limited_by={k: v / n_samples for k, v in counts.items()},
        method=f"Monte Carlo: {n_samples} soils from the fit's Gaussian ({uncertainty.source}), clipped to the "
        "bounds, each steady turn solved and checked against the soil, torque and power limits",
    )
