"""An independent plain-numpy implementation of the Wong-Reece rigid wheel: the tests' oracle.

Written from the textbook equations (Wong, Theory of Ground Vehicles, ch. 5; Wong and Reece 1967),
not from soilmodel/wheel.py: a dense trapezoid rule in theta instead of Gauss-Legendre, the
stresses evaluated pointwise, the sinkage from the load by bisection.
"""

from __future__ import annotations

import math

import numpy as np

#: Points of the trapezoid rule on each side of theta_m (dense: the oracle's own accuracy).
POINTS = 4001


def _trapz(y, x):
    """Trapezoid rule (numpy 2 renamed np.trapz; written out here)."""
    return float(np.sum((y[1:] + y[:-1]) * np.diff(x)) / 2)


def stresses(theta, i, th1, c, phi, K, k, n, r, h, c1, c2, s=0.0, b=None, grousers="bekker"):
    """sigma, tau (Pa) at angles theta (rad) of a wheel with entry angle th1.

    With grousers (h > 0, ``b`` given, ``grousers="bekker"``) Bekker's grousered shear strength
    c (1 + 2 h/b) + sigma tan(phi) (1 + 0.64 (h/b) arccot(h/b)) (Bekker 1956, as Wong quotes it).
    """
    thm = (c1 + c2 * i) * th1
    ke = k / (1.0 + s * i)
    sigma = np.empty_like(theta)
    front = theta >= thm
    sigma[front] = ke * r**n * np.clip(np.cos(theta[front]) - math.cos(th1), 0, None) ** n
    th_eq = th1 - theta[~front] / thm * (th1 - thm)
    sigma[~front] = ke * r**n * np.clip(np.cos(th_eq) - math.cos(th1), 0, None) ** n
    j = (r + h) * ((th1 - theta) - (1 - i) * (math.sin(th1) - np.sin(theta)))
    fc = fphi = 1.0
    if h > 0 and b is not None and grousers == "bekker":
        fc, fphi = 1 + 2 * h / b, 1 + 0.64 * (h / b) * math.atan2(1.0, h / b)
    tau = (c * fc + sigma * math.tan(phi) * fphi) * (1 - np.exp(-j / K))
    return sigma, tau


def forces(i, z, c, phi, K, k, n, r, b, h=0.0, c1=0.4, c2=0.15, s=0.0, grousers="bekker"):
    """(drawbar pull N, normal load N, torque N m) of one row."""
    th1 = math.acos(1 - z / r)
    thm = (c1 + c2 * i) * th1
    out = np.zeros(3)
    for lo, hi in ((0.0, thm), (thm, th1)):
        th = np.linspace(lo, hi, POINTS)
        sig, tau = stresses(th, i, th1, c, phi, K, k, n, r, h, c1, c2, s, b=b, grousers=grousers)
        out += [
            _trapz(tau * np.cos(th) - sig * np.sin(th), th),
            _trapz(sig * np.cos(th) + tau * np.sin(th), th),
            _trapz(tau, th),
        ]
    return r * b * out[0], r * b * out[1], (r + h) ** 2 * b * out[2]


def sinkage(i, W, c, phi, K, k, n, r, b, h=0.0, c1=0.4, c2=0.15, s=0.0):
    """Sinkage (m) at which the wheel carries W, by bisection on (0, r)."""
    lo, hi = 1e-7, 0.999 * r
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if forces(i, mid, c, phi, K, k, n, r, b, h, c1, c2, s)[1] < W:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def sweep(slips, loads, c, phi, K, k, n, r, b, h=0.0, s=0.0, sd_dp=0.0, sd_z=0.0, seed=0):
    """A simulated rig sweep: (slip, drawbar pull, load, sinkage) arrays, with optional noise."""
    rng = np.random.default_rng(seed)
    rows = []
    for W in loads:
        for i in slips:
            z = sinkage(i, W, c, phi, K, k, n, r, b, h, s=s)
            dp = forces(i, z, c, phi, K, k, n, r, b, h, s=s)[0]
            rows.append((i, dp + rng.normal(0, sd_dp) if sd_dp else dp, W, z + rng.normal(0, sd_z) if sd_z else z))
    return tuple(np.array(col) for col in zip(*rows))
