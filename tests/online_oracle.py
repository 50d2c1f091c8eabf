"""An independent drive-log simulator for the on-line estimator's tests and benchmark (no library code).

Written out here in plain Python on purpose: the logs the estimator is checked on must not come
from the code under test. Straight-line tracked vehicle, Janosi-Hanamoto thrust
``F = F_max (1 - K/(i l) (1 - exp(-i l/K)))`` (the seed's Eq. 2, skid ``F(-i) = -F(i)``), the sprocket
equation ``I dw/dt = M - r F(i)`` integrated by implicit Euler (a scalar Newton/bisection solve
per sub-step: the slip settles in milliseconds), the hull ``m dv/dt = F - R`` by explicit Euler,
``R = N mu_r + W sin(theta) + D(t)`` with a drawbar load ``D`` during the "pulls" (the thrust then
ramps up to ``level * F_max`` over the first quarter of the pull and stays there, at a held speed:
a pull sweeping the thrust-slip curve up to near the traction limit). A PI speed controller
with feed-forward updates the torque at the log rate and holds it (zero-order hold). Sensor noise:
torque 1 % + 0.1 % of ``0.8 W r``, encoder 0.5 % + 0.01 rad/s, speed ``speed_noise``.
"""

from __future__ import annotations

import math
import random

G = 9.81
#: Share of a pull over which its drawbar load ramps up (then it is held until the pull ends).
RAMP = 0.25
#: The two reference vehicles: W (N), l, b, r (m), I (kg m^2), mu_r, cruise speed (m/s), speed noise (m/s).
VEHICLES = {
    "heavy": dict(W=329e3, l=2.8, b=0.5, r=0.3, I=500.0, mu=0.05, v=3.0, sv=0.05),
    "light": dict(W=300.0, l=0.5, b=0.1, r=0.08, I=0.05, mu=0.05, v=1.0, sv=0.02),
}
#: Soils as (c Pa, phi rad, K m).
SOILS = {
    "lete_sand": (1300.0, math.radians(31.1), 0.012),
    "weak": (600.0, math.radians(24.2), 0.012),  # heavy: F_max 202.1 -> 149.3 kN
}


def f_max(soil, veh: dict, grade_rad: float = 0.0) -> float:
    """``A c + N tan(phi)`` with ``A = 2 b l`` and ``N = W cos(theta)``."""
    c, phi, _ = soil
    return 2 * veh["b"] * veh["l"] * c + veh["W"] * math.cos(grade_rad) * math.tan(phi)


def _shape(i: float, l: float, K: float) -> float:
    u = abs(i) * l / K
    g = u / 2 - u * u / 6 if u < 1e-6 else 1 - (1 - math.exp(-u)) / u
    return g if i >= 0 else -g


def _sprocket(w: float, v: float, M: float, dt: float, veh: dict, F: float, K: float) -> float:
    """Implicit Euler step of the sprocket speed: ``I (w' - w)/dt = M - r F(i(v, w'))``."""
    r, I, l = veh["r"], veh["I"], veh["l"]

    def res(x):
        rw = r * x
        i = 1 - v / rw if rw > 1e-9 else 0.0
        i = max(min(i, 0.99), -0.99)
        return I * (x - w) / dt - M + r * F * _shape(i, l, K)

    lo, hi = max(v / r * 0.0, 1e-6), max(w, v / r) * 2 + 10.0
    rlo = res(lo)
    if rlo > 0:
        return lo
    for _ in range(60):  # bisection on a monotone residual
        mid = 0.5 * (lo + hi)
        if res(mid) > 0:
            hi = mid
        else:
            lo = mid
        if hi - lo < 1e-10 * max(1.0, hi):
            break
    return 0.5 * (lo + hi)


def simulate(
    vehicle: str,
    soil_at,
    duration: float,
    pulls,
    *,
    rate: float = 50.0,
    substeps: int = 10,
    grade_deg: float = 0.0,
    seed: int = 0,
    drop_frac: float = 0.0,
) -> dict:
    """Simulate a log; ``soil_at(t) -> (c, phi, K)``; ``pulls`` a list of ``(t0, t1, level)``.

    Returns columns ``time_s``, ``sprocket_torque_Nm``, ``sprocket_speed_rad_s``,
    ``vehicle_speed_m_s`` (lists, NaN where a reading was dropped) and the truth ``F_max``,
    ``K`` and ``thrust`` per sample (at ``N = W cos(theta)``).
    """
    veh = VEHICLES[vehicle]
    rnd = random.Random(seed)
    th = math.radians(grade_deg)
    W, r, m = veh["W"], veh["r"], veh["W"] / G
    N = W * math.cos(th)
    base = N * veh["mu"] + W * math.sin(th)
    v_ref = veh["v"]
    v = v_ref
    c0 = soil_at(0.0)
    w = v / (r * (1 - 0.01))
    M_max = max(0.8 * W * r, 1.1 * r * f_max(c0, veh, th)) * 1.5
    integ = 0.0
    h = 1.0 / rate
    dt = h / substeps
    keys = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s", "F_max", "K", "thrust")
    out: dict = {k: [] for k in keys}
    n = int(round(duration * rate)) + 1
    kp, ki = 2.0, 1.0
    for k in range(n):
        t = k * h
        soil = soil_at(t)
        F = f_max(soil, veh, th)
        K = soil[2]
        level = max((lv * min(1.0, (t - a) / (RAMP * (b - a))) for a, b, lv in pulls if a <= t < b), default=0.0)
        R = max(base, level * F)
        e = v_ref - v
        M = r * (R + m * (kp * e + ki * integ))
        M = min(max(M, -M_max), M_max)
        integ += e * h
        sM = math.hypot(0.01 * M, 0.001 * 0.8 * W * r)
        sw = math.hypot(0.005 * w, 0.01)
        row = [t, M + rnd.gauss(0, sM), w + rnd.gauss(0, sw), v + rnd.gauss(0, veh["sv"])]
        if drop_frac and rnd.random() < drop_frac:
            row[rnd.randrange(1, 4)] = float("nan")
        for key, val in zip(("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s"), row):
            out[key].append(val)
        out["F_max"].append(F)
        out["K"].append(K)
        rw0 = r * w
        i0 = max(min(1 - v / rw0 if rw0 > 1e-9 else 0.0, 0.99), -0.99)
        out["thrust"].append(F * _shape(i0, veh["l"], K))
        for _ in range(substeps):
            w = _sprocket(w, v, M, dt, veh, F, K)
            rw = r * w
            i = max(min(1 - v / rw if rw > 1e-9 else 0.0, 0.99), -0.99)
            Ft = F * _shape(i, veh["l"], K)
            v = max(v + dt * (Ft - R) / m, 0.0)
    return out


def random_pulls(duration: float, every: tuple[float, float], length: tuple[float, float], level, seed: int):
    """Pulls at random times: gaps drawn uniformly in ``every`` s, lengths in ``length`` s, level(s)."""
    rnd = random.Random(seed + 1000)
    t, out = rnd.uniform(0.5, 2.0), []
    while t < duration - 1.0:
        ln = rnd.uniform(*length)
        lv = level if isinstance(level, float) else rnd.uniform(*level)
        out.append((t, t + ln, lv))
        t += ln + rnd.uniform(*every)
    return out


def write_csv(cols: dict, path: str) -> None:
    """The log's four channels as a drive-log CSV (empty cells where dropped)."""
    keys = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s")
    with open(path, "w") as f:
        f.write(",".join(keys) + "\n")
        for row in zip(*(cols[k] for k in keys)):
            f.write(",".join("" if x != x else repr(float(x)) for x in row) + "\n")
