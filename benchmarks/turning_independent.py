"""An independent plain-numpy two-track turning simulator: the oracle of the steering fit (issue 42).

Written from Wong and Chiang's skid-steering theory as docs/physics.md states it, NOT from
``soiltrack.soilmodel.steering``: it imports nothing of soiltrack, and where the library uses the
steady closed form of the shear displacement this simulator accumulates it in time.

Model (hull frame: x forward, y left, origin at the patches' centre; yaw rate Om + left):

- Each track's belt in contact is a row of material nodes ``ds`` apart (``n_along`` over the
  length l, ``n_across`` midpoint points across the width b). The belt moves rearwards under the
  hull at ``r w_k``; a node enters at the front with zero shear displacement and leaves at the rear.
- A node at (x, y) slides over the ground with ``V = (u - Om y - r w_k, v + Om x)``; its shear
  displacement ``j`` (ground frame: V rotated by the heading) is accumulated from its entry by the
  trapezoid rule over each time step (the history of a changing motion, not a steady closed form).
- Janosi-Hanamoto shear ``tau = (c + p_k tan(phi)) (1 - exp(-|j|/K))`` acts against the CURRENT
  sliding direction ``-V/|V|`` at each node; uniform pressure ``p_k = W_k / (b l)`` per track with the
  lateral load transfer ``W_left,right = W/2 -+ m a_y h / B``, ``a_y = dv/dt + u Om``.
- The forces and the yaw moment are integrated over [0, l] of each track by the piecewise-linear
  interpolant of the node values (a zero node at the entry, the rear end interpolated); motion
  resistance ``mu_r W_k`` along each track.
- Planar dynamics ``m (du/dt - v Om) = X``, ``m (dv/dt + u Om) = Y``, ``Iz dOm/dt = N`` and each
  sprocket ``(I/2) dw_k/dt = T_k - r F_x,k``, integrated by IMPLICIT Euler (step ``dt``; Newton with a
  finite-difference Jacobian and backtracking on u and the slides v, l Om, u - r w_k, each through
  ``eps sinh(xi)``: the Coulomb-like sliding direction is stiff near V = 0, and plain Newton failed
  at a track's stick; a step Newton does not solve is taken as two half steps).
- Drive: a PI speed servo per sprocket (``bandwidth`` rad/s on the sprocket with half the hull's mass
  locked to it; conditional integration against wind-up) at ``control_hz``, its torque held between
  ticks and limited per track by ``max_torque`` and ``max_power / |w|``. Its references are the
  kinematic sprocket speeds ``(u_ref -+ Om_ref B/2) / r`` of a random plan per seed: a cruise at
  1.6-2.2 m/s, straight hard pulls (+0.8-1.5 m/s for 2-3 s, then a 2 s ramp down) and turns of
  kinematic radius 8-25 m, alternating left and right, 4-7 s each with the curvature ramped over 1 s.
- The log starts after ``warmup_s`` (the start has no shear history). Sensor noise, white and
  Gaussian, per channel ``sqrt(abs^2 + (rel |x|)^2)``, added to the sampled true signals.

Columns written: ``time_s``, ``sprocket_torque_left_Nm``, ``sprocket_torque_right_Nm``,
``sprocket_speed_left_rad_s``, ``sprocket_speed_right_rad_s``, ``vehicle_speed_m_s`` (forward speed at
the centre), ``yaw_rate_rad_s`` (docs/data-formats.md). Several seeds are simulated at once (vectorised).

    python benchmarks/turning_independent.py --seed 1 -o log.csv --vehicle-json veh.json
    python benchmarks/turning_independent.py --seed 1 --soil clayey_soil -o log.csv
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass, replace

import numpy as np

G = 9.81
#: Regularising speed of the sliding direction V / sqrt(|V|^2 + eps^2), m/s.
SLIDE_EPS = 1e-5


@dataclass(frozen=True)
class Vehicle:
    """The heavy tracked vehicle (W = 329 kN) with a tread and a centre of gravity height.

    Attributes
    ----------
    weight, length, width, tread, radius, inertia, mu_r, cg_height
        W (N), track length l, width b (one track), tread B (m), sprocket radius r (m), inertia of
        both sprockets I (kg m^2), motion resistance coefficient, height h of the centre of gravity (m).
    max_torque, max_power
        Drive limits of ONE track, N m and W.
    """

    weight: float = 329_000.0
    length: float = 2.8
    width: float = 0.5
    tread: float = 2.5
    radius: float = 0.3
    inertia: float = 500.0
    mu_r: float = 0.05
    cg_height: float = 1.0
    max_torque: float = 40_000.0
    max_power: float = 300_000.0

    @property
    def mass(self) -> float:
        """m = W / g."""
        return self.weight / G

    @property
    def yaw_inertia(self) -> float:
        """Iz of a uniform box over the tracks, ``m (l^2 + (B + b)^2) / 12`` (written into the vehicle JSON)."""
        return self.mass * (self.length**2 + (self.tread + self.width) ** 2) / 12.0

    def json(self) -> dict:
        """The vehicle file of docs/data-formats.md (limits of both tracks together)."""
        return {
            "name": "heavy, independent turning simulator",
            "mass_kg": self.mass,
            "track_length_m": self.length,
            "track_width_m": self.width,
            "sprocket_radius_m": self.radius,
            "sprocket_inertia_kg_m2": self.inertia,
            "rolling_resistance": self.mu_r,
            "max_sprocket_torque_Nm": 2 * self.max_torque,
            "max_power_W": 2 * self.max_power,
            "tread_m": self.tread,
            "yaw_inertia_kg_m2": self.yaw_inertia,
            "cg_height_m": self.cg_height,
        }


@dataclass(frozen=True)
class Soil:
    """Cohesion c (Pa), friction angle (deg), shear modulus K (m)."""

    c: float
    phi_deg: float
    K: float

    def max_thrust(self, veh: Vehicle) -> float:
        """F_max = 2 b l c + W tan(phi) (both tracks)."""
        return 2 * veh.width * veh.length * self.c + veh.weight * math.tan(math.radians(self.phi_deg))


#: Three soils (docs/physics.md's terrain table, restated).
SOILS = {
    "lete_sand": Soil(1300.0, 31.1, 0.012),
    "clayey_soil": Soil(4140.0, 13.0, 0.006),
    "dry_sand": Soil(1040.0, 28.0, 0.025),
}


@dataclass(frozen=True)
class Grid:
    """Discretisation: nodes along and across each track, the time step.

    Attributes
    ----------
    n_along
        Node spacing ``ds = l / n_along`` along the belt (the belt must move less than ``ds`` a step).
    n_across
        Midpoint points across each track's width.
    dt
        Implicit-Euler step, s (must divide the control period).
    """

    n_along: int = 60
    n_across: int = 4
    dt: float = 0.005


@dataclass(frozen=True)
class Noise:
    """Sensor noise (standard deviations).

    Attributes
    ----------
    torque_abs, torque_rel
        Each track's torque: N m (0.1 % of 40 kN m) and relative to the reading.
    encoder_abs, encoder_rel
        Each sprocket's speed: rad/s and relative.
    gnss
        Forward speed, m/s.
    gyro
        Yaw rate, rad/s.
    """

    torque_abs: float = 40.0
    torque_rel: float = 0.01
    encoder_abs: float = 0.01
    encoder_rel: float = 0.005
    gnss: float = 0.05
    gyro: float = 0.005


@dataclass(frozen=True)
class Drive:
    """The sprocket speed servos and the rates.

    Attributes
    ----------
    bandwidth
        Closed-loop bandwidth of each sprocket's PI servo, rad/s (critically damped).
    control_hz, rate_hz
        Servo rate and log rate, Hz.
    warmup_s
        Simulated before the log starts, s (longer than a node's contact time).
    """

    bandwidth: float = 4.0
    control_hz: float = 100.0
    rate_hz: float = 25.0
    warmup_s: float = 4.0


def plan(seed: int, duration_s: float, turns: int = 4) -> tuple[list, float]:
    """A random plan: ``[(t0, t1, kind, value)]`` (``pull``: +m/s, ``turn``: kinematic radius, + left), cruise.

    Straight 3-5 s, sometimes a hard pull, then a turn; turns alternate in sign (random first side).
    """
    rng = np.random.default_rng(20_000 + seed)
    cruise = float(rng.uniform(1.6, 2.2))
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    t, out = 0.5, []
    while t < duration_s:
        t += rng.uniform(3.0, 5.0)
        if rng.uniform() < 0.6:
            dur = rng.uniform(2.0, 3.0)
            out.append((t, t + dur, "pull", float(rng.uniform(0.8, 1.5))))
            t += dur + 2.0 + 2.0
        if len([o for o in out if o[2] == "turn"]) < turns:
            dur = rng.uniform(4.0, 7.0)
            out.append((t, t + dur, "turn", sign * float(rng.choice([8.0, 10.0, 12.0, 15.0, 20.0, 25.0]))))
            sign, t = -sign, t + dur
    return [o for o in out if o[1] <= duration_s], cruise


def _ramp(t, t0, T):
    s = np.clip((t - t0) / T, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * s)


def reference(t: float, items: list, cruise: float) -> tuple[float, float]:
    """(u_ref, kappa_ref) of a plan at time t (pulls: 0.3 s up, 2 s down; turns ramped over 1 s)."""
    u, k = cruise, 0.0
    for t0, t1, kind, val in items:
        if kind == "pull":
            u += val * (_ramp(t, t0, 0.3) - _ramp(t, t1, 2.0))
        else:
            ramp = min(1.0, 0.5 * (t1 - t0))
            k += (_ramp(t, t0, ramp) - _ramp(t, t1 - ramp, ramp)) / val
    return float(u), float(k)


class Plant:
    """The state of ``L`` vehicles (one per seed) and the implicit-Euler step (the module docstring)."""

    def __init__(self, L: int, u0: np.ndarray, veh: Vehicle, soil: Soil, grid: Grid) -> None:
        self.veh, self.soil, self.grid = veh, soil, grid
        self.ds = veh.length / grid.n_along
        self.N = grid.n_along + 3
        b, B = veh.width, veh.tread
        off = -b / 2 + (np.arange(grid.n_across) + 0.5) * b / grid.n_across
        self.y = np.stack([B / 2 + off, -B / 2 + off])  # (2, ny): left, right
        self.q = np.stack([u0, np.zeros(L), np.zeros(L), u0 / veh.radius, u0 / veh.radius], axis=1)  # u v Om wl wr
        self.psi = np.zeros(L)
        self.f = np.zeros((L, 2))  # the newest node's distance behind the front
        self.J = np.zeros((L, 2, self.N, grid.n_across, 2))  # shear displacement, ground frame
        self.Vp = np.zeros_like(self.J)  # each node's sliding velocity (ground frame) at the step's start
        self.Fx = np.zeros((L, 2))
        self.halvings = 0  # steps Newton did not solve, taken as two half steps

    def _transport(self, dt: float):
        """Move the belts by ``r w dt`` (start-of-step speed); a node enters where one more ``ds`` passed."""
        belt = self.veh.radius * self.q[:, 3:5]
        if np.any(belt * dt >= self.ds) or np.any(belt <= 0):
            raise RuntimeError("a belt moved a node spacing in one step or stopped: smaller dt / fewer nodes")
        f = self.f + belt * dt
        entered = f >= self.ds
        f = np.where(entered, f - self.ds, f)
        sh = lambda a: np.concatenate([np.zeros_like(a[:, :, :1]), a[:, :, :-1]], axis=2)  # noqa: E731
        e = entered[:, :, None, None, None]
        J, Vp = np.where(e, sh(self.J), self.J), np.where(e, sh(self.Vp), self.Vp)
        a_new = np.full((*f.shape, self.N), 0.5 * dt)
        a_new[..., 0] = np.where(entered, f / belt, 0.5 * dt)  # a new node: the time since its entry
        return f, J, Vp, a_new

    def _weights(self, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Node positions s (L, 2, N) behind the front and the weights of the linear interpolant over [0, l]."""
        l, ds = self.veh.length, self.ds
        s = f[..., None] + ds * np.arange(self.N)
        Li = np.clip(np.minimum(s[..., 1:], l) - s[..., :-1], 0.0, ds)
        w = np.zeros_like(s)
        w[..., :-1] += Li * (1 - Li / (2 * ds))
        w[..., 1:] += Li**2 / (2 * ds)
        w[..., 0] += 0.5 * s[..., 0]  # [0, s_0]: a zero node at the entry
        return s, w

    def _forces(self, q, f, J, Vp, a_new, dt):
        """Residuals (L, P, 5) of the step for trial speeds q (L, P, 5), and the new J, V, F_x."""
        veh, soil = self.veh, self.soil
        m, W, l, b, B, r = veh.mass, veh.weight, veh.length, veh.width, veh.tread, veh.radius
        u, v, Om, wl, wr = (q[..., k] for k in range(5))
        u0, v0, Om0, wl0, wr0 = (self.q[:, k][:, None] for k in range(5))
        psi = self.psi[:, None] + 0.5 * (Om0 + Om) * dt
        s, wts = self._weights(f)
        x = (0.5 * l - s)[:, None, :, :, None]  # (L, 1, 2, N, 1)
        y = self.y[None, None, :, None, :]  # (1, 1, 2, 1, ny)
        belt = r * np.stack([wl, wr], axis=-1)[..., None, None]  # (L, P, 2, 1, 1)
        Vx = u[..., None, None, None] - Om[..., None, None, None] * y - belt
        Vy = v[..., None, None, None] + Om[..., None, None, None] * x
        c, sn = np.cos(psi)[..., None, None, None], np.sin(psi)[..., None, None, None]
        Vg = np.stack([c * Vx - sn * Vy, sn * Vx + c * Vy], axis=-1)
        Jn = J[:, None] + 0.5 * dt * Vp[:, None] + a_new[:, None, :, :, None, None] * Vg
        ay = (v - v0) / dt + u * Om
        dW = m * ay * veh.cg_height / B
        Wk = np.stack([0.5 * W - dW, 0.5 * W + dW], axis=-1)  # (L, P, 2)
        tmax = soil.c + Wk / (b * l) * math.tan(math.radians(soil.phi_deg))
        tau = tmax[..., None, None] * -np.expm1(-np.sqrt((Jn**2).sum(-1) + 1e-30) / soil.K)
        sp = np.sqrt(Vx**2 + Vy**2 + SLIDE_EPS**2)
        dA = wts[:, None, :, :, None] * (b / self.grid.n_across)
        fx, fy = -tau * Vx / sp * dA, -tau * Vy / sp * dA
        Fx, Fy = fx.sum((-1, -2)), fy.sum((-1, -2))  # (L, P, 2)
        Mz = (x * fy - y * fx).sum((-1, -2))
        R = veh.mu_r * Wk
        X = Fx.sum(-1) - R.sum(-1)
        Y = Fy.sum(-1)
        N = Mz.sum(-1) + 0.5 * B * (R[..., 0] - R[..., 1])
        Tq = self.T[:, None, :]
        res = np.stack(
            [
                (m * ((u - u0) / dt - v * Om) - X) / W,
                (m * ((v - v0) / dt + u * Om) - Y) / W,
                (veh.yaw_inertia * (Om - Om0) / dt - N) / (W * l),
                (0.5 * veh.inertia * (wl - wl0) / dt - (Tq[..., 0] - r * Fx[..., 0])) / (W * r),
                (0.5 * veh.inertia * (wr - wr0) / dt - (Tq[..., 1] - r * Fx[..., 1])) / (W * r),
            ],
            axis=-1,
        )
        return res, Jn, Vg, Fx, psi

    def step(self, T: np.ndarray, dt: float, depth: int = 0) -> None:
        """One implicit-Euler step under the held torques T (L, 2); where Newton fails, two half steps."""
        try:
            self._step(T, dt)
        except RuntimeError:
            if depth >= 6:
                raise
            self.halvings += 1
            self.step(T, 0.5 * dt, depth + 1)
            self.step(T, 0.5 * dt, depth + 1)

    def _step(self, T: np.ndarray, dt: float) -> None:
        self.T = T
        f, J, Vp, a_new = self._transport(dt)
        r, eps = self.veh.radius, SLIDE_EPS

        # unknowns xi: u, and the slides v = eps sinh(xi_1), l Om = eps sinh(xi_2), u - r w_k = eps sinh(xi_k):
        # Newton then steps in the slides' orders of magnitude (the sliding direction is steep near V = 0)
        sc = np.array([eps, eps / self.veh.length, eps, eps])

        def speeds(xi):
            sl = sc * np.sinh(xi[..., 1:5])
            return np.concatenate([xi[..., :1], sl[..., :2], (xi[..., :1] - sl[..., 2:4]) / r], axis=-1)

        q0 = self.q
        slides = np.stack([q0[:, 1], q0[:, 2], q0[:, 0] - r * q0[:, 3], q0[:, 0] - r * q0[:, 4]], axis=1)
        xi = np.concatenate([q0[:, :1], np.arcsinh(slides / sc)], axis=1)
        scale = np.array([1e-8, 1e-7, 1e-7, 1e-7, 1e-7])
        for _ in range(30):  # Newton with backtracking per vehicle
            trial = np.concatenate([xi[:, None, :], xi[:, None, :] + np.diag(scale)[None]], axis=1)
            res, *_ = self._forces(speeds(trial), f, J, Vp, a_new, dt)
            r0 = np.max(np.abs(res[:, 0]), axis=1)
            if np.max(r0) < 1e-11:
                break
            Jac = np.swapaxes((res[:, 1:] - res[:, :1]) / scale[None, :, None], 1, 2)  # (L, 5 res, 5 vars)
            dx = np.linalg.solve(Jac, -res[:, 0][..., None])[..., 0]
            dx[:, 1:5] = np.clip(dx[:, 1:5], -2.0, 2.0)  # a sinh's argument: at most a factor e^2 a step
            lam = np.ones(xi.shape[0])
            for _ in range(20):
                rt, *_ = self._forces(speeds(xi + lam[:, None] * dx)[:, None, :], f, J, Vp, a_new, dt)
                worse = np.max(np.abs(rt[:, 0]), axis=1) >= r0 * (1 - 1e-4 * lam)
                if not worse.any():
                    break
                lam = np.where(worse, 0.5 * lam, lam)
            xi = xi + lam[:, None] * dx
        q = speeds(xi)
        res, Jn, Vg, Fx, psi = self._forces(q[:, None, :], f, J, Vp, a_new, dt)
        if not np.all(np.isfinite(q)) or np.max(np.abs(res)) > 1e-7:
            raise RuntimeError(f"implicit step not converged (residual {np.max(np.abs(res)):.2e})")
        self.q, self.f, self.J, self.Vp, self.Fx, self.psi = q, f, Jn[:, 0], Vg[:, 0], Fx[:, 0], psi[:, 0]


def simulate(
    seeds,
    duration_s: float = 45.0,
    soil: Soil = SOILS["lete_sand"],
    veh: Vehicle = Vehicle(),
    grid: Grid = Grid(),
    drive: Drive = Drive(),
    noise: Noise | None = Noise(),
    turns: int = 4,
    plans: list | None = None,
) -> list[dict]:
    """Two-track logs for ``seeds`` (each its own plan and noise): column dicts plus ``truth``.

    ``plans`` (one ``(items, cruise)`` per seed, as :func:`plan` returns) replaces the random plans.
    """
    seeds = list(seeds)
    plans = plans if plans is not None else [plan(s, duration_s, turns) for s in seeds]
    L = len(seeds)
    nsub = int(round(1.0 / (drive.control_hz * grid.dt)))
    per_log = int(round(drive.control_hz / drive.rate_hz))
    if abs(nsub * grid.dt * drive.control_hz - 1) > 1e-9 or abs(per_log * drive.rate_hz - drive.control_hz) > 1e-9:
        raise ValueError("dt must divide the control period and the control rate the log rate")
    n_ctrl = int(round((duration_s + drive.warmup_s) * drive.control_hz))
    t_ctrl = np.arange(n_ctrl + 1) / drive.control_hz - drive.warmup_s
    refs = np.array([[reference(t, it, cr) for t in t_ctrl] for it, cr in plans])  # (L, n, 2)
    r, B = veh.radius, veh.tread
    plant = Plant(L, refs[:, 0, 0], veh, soil, grid)
    Jeff = 0.5 * veh.inertia + 0.5 * veh.mass * r * r
    kp, ki = 2.0 * drive.bandwidth * Jeff, drive.bandwidth**2 * Jeff
    z = np.full((L, 2), 0.5 * veh.mu_r * veh.weight * r)
    rows = []
    for k in range(n_ctrl + 1):
        u_ref, kap = refs[:, k, 0], refs[:, k, 1]
        wref = np.stack([u_ref - u_ref * kap * B / 2, u_ref + u_ref * kap * B / 2], axis=1) / r
        w = plant.q[:, 3:5]
        e = wref - w
        T_uns = kp * e + z
        lim = np.minimum(veh.max_torque, veh.max_power / np.maximum(np.abs(w), 1e-9))
        T = np.clip(T_uns, -lim, lim)
        z = np.where((np.abs(T_uns) > lim) & (e * T_uns > 0), z, z + ki * e / drive.control_hz)
        if t_ctrl[k] >= -1e-9 and k % per_log == round(drive.warmup_s * drive.control_hz) % per_log:
            rows.append(np.concatenate([[t_ctrl[k]] * L, T[:, 0], T[:, 1], w[:, 0], w[:, 1], plant.q[:, 0],
                                        plant.q[:, 2], plant.q[:, 1], plant.Fx[:, 0], plant.Fx[:, 1]]))  # fmt: skip
        if k == n_ctrl:
            break
        for _ in range(nsub):
            try:
                plant.step(T, grid.dt)
            except RuntimeError as exc:
                raise RuntimeError(f"t = {t_ctrl[k]:.3f} s: {exc}; speeds {plant.q.tolist()}, torques {T.tolist()}")
    A = np.array(rows).reshape(len(rows), 10, L)
    return [_log(seed, A[:, :, q], plans[q], noise, veh, soil) for q, seed in enumerate(seeds)]


def _log(seed: int, A: np.ndarray, pl, noise: Noise | None, veh: Vehicle, soil: Soil) -> dict:
    rng = np.random.default_rng(seed)
    nz = noise or Noise(0, 0, 0, 0, 0, 0)

    def noisy(x, ab, rel):
        return x + rng.standard_normal(x.size) * np.sqrt(ab**2 + (rel * x) ** 2)

    t, Tl, Tr, wl, wr, u, Om, v, Fxl, Fxr = A.T
    return {
        "time_s": t,
        "sprocket_torque_left_Nm": noisy(Tl, nz.torque_abs, nz.torque_rel),
        "sprocket_torque_right_Nm": noisy(Tr, nz.torque_abs, nz.torque_rel),
        "sprocket_speed_left_rad_s": noisy(wl, nz.encoder_abs, nz.encoder_rel),
        "sprocket_speed_right_rad_s": noisy(wr, nz.encoder_abs, nz.encoder_rel),
        "vehicle_speed_m_s": noisy(u, nz.gnss, 0.0),
        "yaw_rate_rad_s": noisy(Om, nz.gyro, 0.0),
        "truth": {
            "u": u, "v": v, "yaw_rate": Om, "w_left": wl, "w_right": wr, "torque_left": Tl, "torque_right": Tr,
            "Fx_left": Fxl, "Fx_right": Fxr, "F_max": soil.max_thrust(veh), "K": soil.K, "plan": pl[0],
            "cruise": pl[1],
        },
    }  # fmt: skip


COLUMNS = (
    "time_s",
    "sprocket_torque_left_Nm",
    "sprocket_torque_right_Nm",
    "sprocket_speed_left_rad_s",
    "sprocket_speed_right_rad_s",
    "vehicle_speed_m_s",
    "yaw_rate_rad_s",
)


def write_csv(log: dict, path: str) -> None:
    """The log as a two-track drive-log CSV."""
    a = np.column_stack([log[c] for c in COLUMNS])
    np.savetxt(path, a, delimiter=",", comments="", fmt="%.10g", header=",".join(COLUMNS))


def write_vehicle(veh: Vehicle, path: str) -> None:
    """The vehicle JSON."""
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(veh.json(), fh, indent=1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--soil", choices=sorted(SOILS), default="lete_sand")
    ap.add_argument("--duration", type=float, default=45.0, help="log length after the warm-up, s")
    ap.add_argument("--turns", type=int, default=4, help="turns per log (alternating left/right)")
    ap.add_argument("--dt", type=float, default=Grid.dt)
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--vehicle-json", help="also write the vehicle file here")
    a = ap.parse_args(argv)
    (log,) = simulate([a.seed], a.duration, SOILS[a.soil], grid=replace(Grid(), dt=a.dt), turns=a.turns)
    write_csv(log, a.output)
    if a.vehicle_json:
        write_vehicle(Vehicle(), a.vehicle_json)
    tr = log["truth"]
    print(f"wrote {a.output}: {log['time_s'].size} rows, F_max {tr['F_max']:.1f} N, K {tr['K']} m; plan {tr['plan']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
