"""An independent straight-line tracked-vehicle plant for the control tests (plain numpy, no soiltrack code).

Janosi-Hanamoto thrust of both tracks, uniform pressure: F = (2 b l c + N tan(phi)) (1 - K/(i l) (1 - exp(-i l
/ K))), odd in the slip; N = W cos(theta). Hull: m dv/dt = F - W ((mu_r + mu_s |i|) cos(theta) + sin(theta))
(mu_s: slip sinkage, an optional 6th entry of a patch, default 0); sprocket: I dw/dt = M - r F; slip (r w - v)
/ max(r w, v, 1e-3). Each sub-step moves the hull explicitly and solves the stiff sprocket equation by
backward Euler (bisection on w).
"""

from __future__ import annotations

import math

import numpy as np

G = 9.81


class JHPlant:
    def __init__(
        self, mass, l, b, r, I, mu_r, patches, *, dt=0.02, substeps=5, v0=0.5, sigma_v=0.0, sigma_w=0.0, seed=0
    ):
        self.m, self.l, self.b, self.r, self.I, self.mu_r = mass, l, b, r, I, mu_r
        self.patches = [tuple(p) + (0.0,) * (6 - len(p)) for p in patches]  # (length_m, c, phi, K, grade_deg, mu_s)
        self.ends = np.cumsum([p[0] for p in patches])
        self.dt, self.n = dt, substeps
        self.v, self.w, self.x, self.t = v0, v0 / r, 0.0, 0.0
        self.rng = np.random.default_rng(seed)
        self.sv, self.sw = sigma_v, sigma_w
        self.M = 0.0
        self.slip = 0.0

    def patch(self):
        return int(min(np.searchsorted(self.ends, self.x, side="right"), len(self.patches) - 1))

    def thrust(self, i, k):
        _, c, phi, K, g, _ = self.patches[k]
        N = self.m * G * math.cos(math.radians(g))
        Fmax = 2 * self.b * self.l * c + N * math.tan(phi)
        x = abs(i) * self.l / K
        f = x / 2 if x < 1e-6 else 1 - (1 - math.exp(-x)) / x
        return math.copysign(Fmax * f, i)

    def slip_of(self, v, w):
        rw = self.r * w
        return max(min((rw - v) / max(rw, v, 1e-3), 1.0), -1.0)

    def step(self, M):
        self.M = float(M)
        h = self.dt / self.n
        for _ in range(self.n):
            k = self.patch()
            g, mu_s = math.radians(self.patches[k][4]), self.patches[k][5]
            W = self.m * G
            lo, hi = 0.0, max(self.w, self.v / self.r) * 2 + abs(M) * h / self.I + 1.0
            for _ in range(60):  # I (w1 - w) / h = M - r F(i(v, w1)): increasing in w1
                w1 = 0.5 * (lo + hi)
                res = self.I * (w1 - self.w) / h - M + self.r * self.thrust(self.slip_of(self.v, w1), k)
                lo, hi = (w1, hi) if res < 0 else (lo, w1)
            self.w = 0.5 * (lo + hi)
            self.slip = self.slip_of(self.v, self.w)
            F = self.thrust(self.slip, k)
            R_full = W * ((self.mu_r + mu_s * abs(self.slip)) * math.cos(g) + math.sin(g))
            R = R_full if self.v > 1e-3 else min(R_full, max(F, 0.0))
            v_new = max(self.v + h * (F - R) / self.m, 0.0)
            self.x += 0.5 * (self.v + v_new) * h
            self.v = v_new
        self.t += self.dt
        return {
            "time_s": self.t,
            "sprocket_torque_Nm": self.M,
            "sprocket_speed_rad_s": self.w + (self.rng.normal(0, self.sw) if self.sw else 0.0),
            "vehicle_speed_m_s": self.v + (self.rng.normal(0, self.sv) if self.sv else 0.0),
        }


def from_vehicle(V, patches, **kw):
    """A JHPlant of a vehicle object (``mass``, ``track_length``, ``track_width``, ``sprocket_radius``,
    ``sprocket_inertia``, ``rolling_resistance`` attributes) over ``patches`` (tuples as JHPlant's)."""
    return JHPlant(
        V.mass,
        V.track_length,
        V.track_width,
        V.sprocket_radius,
        V.sprocket_inertia,
        V.rolling_resistance,
        patches,
        **kw,
    )


def drive(controller, plant, distance, t_max):
    """Run the loop; returns arrays (t, x, v, slip, M, w) and whether it arrived."""
    meas = plant.step(0.0)
    rows = []
    while plant.x < distance and plant.t < t_max:
        M = controller.command(meas)
        meas = plant.step(M)
        rows.append((plant.t, plant.x, plant.v, plant.slip, float(M), plant.w, meas["sprocket_speed_rad_s"]))
    return np.array(rows), plant.x >= distance


def stuck_events(arr, speed=0.05, slip=0.5, hold=1.0):
    t, v, i = arr[:, 0], arr[:, 2], arr[:, 3]
    n, run, prev = 0, 0.0, t[0]
    for k in range(len(t)):
        dt = t[k] - prev
        prev = t[k]
        run = run + dt if (v[k] < speed and i[k] > slip) else 0.0
        if run > hold and run - dt <= hold:
            n += 1
    return n


def with_truth(plant):
    """Give a JHPlant the ``truth`` the closed loop's metrics read (true distance, slip, F_max, K)."""

    class Truthful(type(plant)):
        @property
        def truth(self):
            k = self.patch()
            _, c, phi, K, g, mu_s = self.patches[k]
            N = self.m * G * math.cos(math.radians(g))
            return {
                "distance_m": self.x,
                "vehicle_speed_m_s": self.v,
                "sprocket_speed_rad_s": self.w,
                "slip": self.slip,
                "patch": k,
                "max_thrust_N": 2 * self.b * self.l * c + N * math.tan(phi),
                "shear_modulus_m": K,
                "slip_sinkage": mu_s,
            }

    plant.__class__ = Truthful
    return plant
