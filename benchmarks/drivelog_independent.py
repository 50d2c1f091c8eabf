"""An independent plain-numpy drive-log simulator (light tracked vehicle, hard pulls): the drive-log fit's oracle.

Written from the equations of docs/physics.md (Eq. 2, the sprocket dynamics), not from ``soiltrack.soilmodel``:
it imports nothing of soiltrack. Eq. 2 (Janosi-Hanamoto thrust of a uniform pressure track, ``F(i) = -F(|i|)`` in
skid), the thrust-balance sprocket equation and Eqs. 1, 4::

    m dv/dt = F(i) - W mu_r,     I dw/dt = M_s - r F(i),     v = r w (1 - i)

integrated by IMPLICIT EULER with a fixed sub-step (default 1 ms; the library's simulator uses CVODES):
each sub-step solves one scalar equation for the slip at its end (Newton, safeguarded by bisection; the
residual is monotone in the slip while the track turns forwards). The drive is a PI speed controller
(critically damped at ``bandwidth`` rad/s, acting on the true speed, conditional integration against
wind-up) whose torque is computed at each sample and HELD until the next (zero-order hold), limited by the
drivetrain's torque and power. The speed reference is a random sequence of hard pulls (steps up by
0.8-2 m/s from a base speed, held, then steps down), different for every seed: thrust peaks from well
inside the curve to the traction limit (track spin). Sensor noise, white and Gaussian, per channel
``sqrt(abs^2 + (rel |x|)^2)``, is added to the sampled signals afterwards.

The log's columns are those of a drive-log CSV: ``time_s, sprocket_torque_Nm`` (the held command, read at
the sample), ``sprocket_speed_rad_s, vehicle_speed_m_s, vehicle_accel_m_s2`` (dv/dt just after the
sample). Several logs (seeds) are simulated at once, vectorised over the seeds.

    python benchmarks/drivelog_independent.py --seed 1 --minutes 10 -o log.csv

Options that change one thing at a time (the bias study of benchmarks/drivelog_independent_bias.py):
``dt`` (the sub-step), ``rate_hz``, the noise of each channel (``Noise``), ``hold`` (``"zoh"``, or
``"sample"``: the torque changes linearly between samples - a first-order hold - instead of being held).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, replace

import numpy as np

G = 9.81


@dataclass(frozen=True)
class Vehicle:
    """The library's light vehicle preset (docs/physics.md), with its drivetrain limits.

    Attributes
    ----------
    weight, length, width, radius, inertia, mu_r
        W (N), track length l and width b (m), sprocket radius r (m), sprocket inertia I (kg m^2),
        rolling resistance mu_r: the light preset's.
    max_torque, max_power
        Drivetrain limits, N m and W (those the library's light preset carries: 40 N m, 500 W).
    """

    weight: float = 300.0
    length: float = 0.5
    width: float = 0.1
    radius: float = 0.08
    inertia: float = 0.05
    mu_r: float = 0.05
    max_torque: float = 40.0
    max_power: float = 500.0

    @property
    def mass(self) -> float:
        """m = W / g."""
        return self.weight / G

    @property
    def area(self) -> float:
        """Contact area of both tracks, A = 2 b l."""
        return 2.0 * self.width * self.length


@dataclass(frozen=True)
class Soil:
    """Dry sand (docs/physics.md's terrain table; K = 25 mm, the library's value for it).

    Attributes
    ----------
    c, phi_deg, K
        Cohesion (Pa), friction angle (deg), shear modulus (m).
    """

    c: float = 1040.0
    phi_deg: float = 28.0
    K: float = 0.025

    def max_thrust(self, veh: Vehicle) -> float:
        """F_max = A c + W tan(phi)."""
        return veh.area * self.c + veh.weight * math.tan(math.radians(self.phi_deg))


@dataclass(frozen=True)
class Noise:
    """Sensor noise levels (the library's documented defaults, restated).

    Attributes
    ----------
    torque_abs, torque_rel
        Torque: N m absolute (0.1 % of the 40 N m limit) and relative (1 % of reading).
    encoder_abs, encoder_rel
        Sprocket speed: rad/s absolute and relative.
    gnss
        Vehicle speed, m/s.
    imu
        Acceleration, m/s^2.
    """

    torque_abs: float = 0.04
    torque_rel: float = 0.01
    encoder_abs: float = 0.01
    encoder_rel: float = 0.005
    gnss: float = 0.05
    imu: float = 0.05

    def scaled(self, torque: float = 1.0, encoder: float = 1.0, gnss: float = 1.0, imu: float = 1.0) -> "Noise":
        """These levels with each channel's scaled (0: that channel noise-free)."""
        return replace(
            self,
            torque_abs=self.torque_abs * torque,
            torque_rel=self.torque_rel * torque,
            encoder_abs=self.encoder_abs * encoder,
            encoder_rel=self.encoder_rel * encoder,
            gnss=self.gnss * gnss,
            imu=self.imu * imu,
        )


def thrust(i: np.ndarray, veh: Vehicle, soil: Soil) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 2 and its slip derivative: ``F = F_max B(|i| l / K) sign(i)``, ``B(x) = 1 - (1 - e^-x) / x``."""
    fmax = soil.max_thrust(veh)
    s = veh.length / soil.K
    x = np.abs(i) * s
    small = x < 1e-4
    xs = np.where(small, 1.0, x)
    em = np.exp(-xs)
    B = np.where(small, x / 2 - x**2 / 6 + x**3 / 24, 1.0 - (1.0 - em) / xs)
    dB = np.where(small, 0.5 - x / 3 + x**2 / 8, (1.0 - (1.0 + xs) * em) / xs**2)
    return fmax * B * np.sign(i), fmax * s * dB


def _substep(v, w, i, M, dt, veh: Vehicle, soil: Soil):
    """One implicit-Euler sub-step: the slip ``i+`` with ``r w+ (1 - i+) = v+``, and ``v+, w+``."""
    r, I, m, R = veh.radius, veh.inertia, veh.mass, veh.weight * veh.mu_r
    lo, hi = np.full_like(v, -0.95), np.full_like(v, 0.999)
    x = np.clip(i, lo, hi)
    for _ in range(40):
        F, dF = thrust(x, veh, soil)
        wp = w + dt / I * (M - r * F)
        g = r * wp * (1.0 - x) - v - dt / m * (F - R)
        dg = -r * wp - r * r * dt / I * (1.0 - x) * dF - dt / m * dF
        lo = np.where(g > 0, x, lo)  # g decreases in i (w+ > 0)
        hi = np.where(g > 0, hi, x)
        xn = x - g / dg
        bad = (xn < lo) | (xn > hi) | ~np.isfinite(xn)
        xn = np.where(bad, 0.5 * (lo + hi), xn)
        if np.max(np.abs(xn - x)) < 1e-13:
            x = xn
            break
        x = xn
    F, _ = thrust(x, veh, soil)
    return x, v + dt / m * (F - R), w + dt / I * (M - r * F)


def pull_profile(seed: int, duration_s: float, rate_hz: float) -> np.ndarray:
    """A random speed reference of hard pulls, one value per sample (m/s).

    Base speed 0.8-1.3 m/s held 1-3 s, then a step up by 0.8-2.0 m/s held 1-3 s, then back: repeated.
    """
    rng = np.random.default_rng(10_000 + seed)
    n = int(round(duration_s * rate_hz)) + 1
    out = np.empty(n)
    k = 0
    while k < n:
        base = rng.uniform(0.8, 1.3)
        k1 = min(n, k + int(rng.uniform(1.0, 3.0) * rate_hz))
        out[k:k1] = base
        k2 = min(n, k1 + int(rng.uniform(1.0, 3.0) * rate_hz))
        out[k1:k2] = base + rng.uniform(0.8, 2.0)
        k = k2
    return out


def simulate(
    seeds,
    duration_s: float = 600.0,
    rate_hz: float = 50.0,
    dt: float = 1e-3,
    noise: Noise | None = Noise(),
    veh: Vehicle = Vehicle(),
    soil: Soil = Soil(),
    bandwidth: float = 3.0,
    hold: str = "zoh",
) -> list[dict]:
    """Drive logs for ``seeds`` (each its own pulls and noise): a list of column dicts plus ``truth``.

    Each dict holds ``time_s, sprocket_torque_Nm, sprocket_speed_rad_s, vehicle_speed_m_s,
    vehicle_accel_m_s2`` (noisy) and ``truth``: the noise-free ``v, w, slip, torque`` and ``F_max``, ``K``.
    """
    seeds = list(seeds)
    h = 1.0 / rate_hz
    nsub = int(round(h / dt))
    if abs(nsub * dt - h) > 1e-12 * h or hold not in ("zoh", "sample"):
        raise ValueError("dt must divide the sample interval; hold is 'zoh' or 'sample'")
    ref = np.stack([pull_profile(s, duration_s, rate_hz) for s in seeds])
    L, n = ref.shape
    r, m_eq = veh.radius, veh.mass + veh.inertia / veh.radius**2
    R = veh.weight * veh.mu_r
    v = ref[:, 0].copy()
    F0 = R  # steady state at the first reference speed: thrust = resistance
    i = np.full(L, _slip_of(F0, veh, soil))
    w = v / (r * (1.0 - i))
    z = np.zeros(L)
    V, W, S, T, A = (np.empty((L, n)) for _ in range(5))
    kp, ki = 2.0 * bandwidth, bandwidth**2
    M_prev = np.full(L, r * R)
    for k in range(n):
        e = ref[:, k] - v
        M_uns = r * (m_eq * (kp * e + z) + R)
        lim = np.minimum(veh.max_torque, veh.max_power / np.maximum(np.abs(w), 1e-9))
        M = np.clip(M_uns, -lim, lim)
        z = np.where((np.abs(M_uns) > lim) & (e * M_uns > 0), z, z + h * ki * e)
        V[:, k], W[:, k], S[:, k], T[:, k] = v, w, i, M
        A[:, k] = (thrust(i, veh, soil)[0] - R) / veh.mass
        if k == n - 1:
            break
        for j in range(nsub):
            Mj = M if hold == "zoh" else M_prev + (M - M_prev) * (j + 1) / nsub
            i, v, w = _substep(v, w, i, Mj, dt, veh, soil)
        M_prev = M
    return [_with_noise(seed, h, V[q], W[q], S[q], T[q], A[q], noise, veh, soil) for q, seed in enumerate(seeds)]


def _slip_of(F: float, veh: Vehicle, soil: Soil) -> float:
    """The slip where Eq. 2 gives the thrust F (bisection)."""
    lo, hi = 0.0, 0.999
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if thrust(np.array([mid]), veh, soil)[0][0] < F:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _with_noise(seed, h, v, w, s, M, a, noise: Noise | None, veh: Vehicle, soil: Soil) -> dict:
    rng = np.random.default_rng(seed)
    nz = noise or Noise().scaled(0, 0, 0, 0)

    def noisy(x, ab, rel):
        return x + rng.standard_normal(x.size) * np.sqrt(ab**2 + (rel * x) ** 2)

    return {
        "time_s": np.arange(v.size) * h,
        "sprocket_torque_Nm": noisy(M, nz.torque_abs, nz.torque_rel),
        "sprocket_speed_rad_s": noisy(w, nz.encoder_abs, nz.encoder_rel),
        "vehicle_speed_m_s": noisy(v, nz.gnss, 0.0),
        "vehicle_accel_m_s2": noisy(a, nz.imu, 0.0),
        "truth": {"v": v, "w": w, "slip": s, "torque": M, "F_max": soil.max_thrust(veh), "K": soil.K},
    }


COLUMNS = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s", "vehicle_accel_m_s2")


def write_csv(log: dict, path: str) -> None:
    """The log as a drive-log CSV (the columns of docs/data-formats.md)."""
    a = np.column_stack([log[c] for c in COLUMNS])
    np.savetxt(path, a, delimiter=",", comments="", fmt="%.9g", header=",".join(COLUMNS))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=50.0)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)
    (log,) = simulate([a.seed], duration_s=60.0 * a.minutes, rate_hz=a.rate, dt=a.dt)
    write_csv(log, a.output)
    print(f"wrote {a.output}: {log['time_s'].size} rows, F_max {log['truth']['F_max']:.2f} N, K {log['truth']['K']} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
