"""``soiltrack margin --turn-radius`` on both sides of the feasibility limit found by independent code.

The independent steady turn is benchmarks/steering_independent.py's numpy model (a midpoint grid
over each patch, the shear displacement summed NUMERICALLY along each point's path, the sliding
direction at every point, uniform pressure with the lateral load transfer; no soiltrack code). Here
the hull's forward speed u and yaw rate ``Om = u / R`` are prescribed and Newton (finite-difference
Jacobian) solves the steady balances ``X + m v Om = 0``, ``Y = m u Om``, ``N = 0`` for the two
sprocket speeds and the lateral speed. A turn is feasible (the documented rules of ``margin
--turn-radius``, docs/planning.md) when it has a steady solution with both sprockets forwards, the
sideslip is within 10 deg, the outer track's slip within ``--max-slip`` (0.2), each sprocket torque
within half the drivetrain's limit and the driving power within the limit. The limit radius R* is
found by bisection on log R with the independent model; then ``soiltrack margin --vehicle V
--terrain T --turn-radius R --speed S --json`` is run at ``R* (1 + d)`` (must say feasible, exit 0)
and ``R* (1 - d)`` (must say not feasible, exit 1), turning left and right.

    python benchmarks/turn_margin_independent.py
    python benchmarks/turn_margin_independent.py --speeds 2 4 --delta 0.03
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import steering_independent as si  # noqa: E402
import turning_independent as ti  # noqa: E402

MAX_SIDESLIP_DEG = 10.0


def prescribed_turn(u: float, R: float, soil, veh, grid, z0=None):
    """``(ok, w_l, w_r, v, T_l, T_r)`` of the steady turn at forward speed u and ``Om = u / R`` (independent)."""
    m, r, W, l = veh[0], veh[4], veh[0] * 9.81, veh[1]
    Om = u / R

    def res(z):
        X, Y, N, *_ = si._forces(np, (u, z[2], Om), z[0], z[1], soil, veh, *grid)
        return np.array([(X + m * z[2] * Om) / W, (Y - m * u * Om) / W, N / (W * l)])

    B = veh[3]
    z = np.array(z0 if z0 is not None else [(u - Om * B / 2) / (0.97 * r), (u + Om * B / 2) / (0.97 * r), 0.0])
    for _ in range(50):
        if min(z[0], z[1]) <= 0:
            return (False, *z, math.nan, math.nan)
        f = res(z)
        if np.max(np.abs(f)) < 1e-10:
            break
        J = np.empty((3, 3))
        for k in range(3):
            dz = np.zeros(3)
            dz[k] = 1e-7 * max(1.0, abs(z[k]))
            J[:, k] = (res(z + dz) - f) / dz[k]
        try:
            step = np.linalg.solve(J, -f)
        except np.linalg.LinAlgError:
            return (False, *z, math.nan, math.nan)
        lam = 1.0
        while lam > 1e-4 and np.max(np.abs(res(z + lam * step))) >= np.max(np.abs(f)):
            lam *= 0.5
        z = z + lam * step
    f = res(z)
    _, _, _, fxl, fxr = si._forces(np, (u, z[2], Om), z[0], z[1], soil, veh, *grid)
    ok = bool(np.max(np.abs(f)) < 1e-8 and min(z[0], z[1]) > 0)
    return ok, z[0], z[1], z[2], r * fxl, r * fxr


def feasible(u: float, R: float, soil, veh, grid, limits, max_slip: float) -> tuple[bool, str]:
    """The rules of ``margin --turn-radius`` applied to the independent steady turn."""
    ok, wl, wr, v, Tl, Tr = prescribed_turn(u, R, soil, veh, grid)
    if not ok:
        return False, "no steady turn"
    r, B, Om = veh[4], veh[3], u / R
    sl, sr = 1 - (u - Om * B / 2) / (r * wl), 1 - (u + Om * B / 2) / (r * wr)
    outer = sr if R > 0 else sl
    if math.degrees(math.atan2(abs(v), u)) > MAX_SIDESLIP_DEG:
        return False, "sideslip"
    if outer > max_slip:
        return False, f"outer slip {outer:.3f}"
    if max(abs(Tl), abs(Tr)) > limits[0]:
        return False, f"torque {max(abs(Tl), abs(Tr)):.0f} N m"
    if max(Tl * wl, 0.0) + max(Tr * wr, 0.0) > limits[1]:
        return False, "power"
    return True, f"outer slip {outer:.3f}, torques {Tl:.0f} / {Tr:.0f} N m"


def limit_radius(u, soil, veh, grid, limits, max_slip, steps: int = 22) -> float | None:
    """Smallest feasible R (left turn) by bisection on log R between half the tread and 60 m.

    (Nearly straight, R of hundreds of metres, the inner track slides almost only sideways and this
    plain Newton does not converge; the limits of interest are well inside 60 m.)
    """
    lo, hi = 0.5 * veh[3] * 1.001, 60.0
    while not feasible(u, hi, soil, veh, grid, limits, max_slip)[0]:
        hi *= 0.5  # (or this Newton did not converge there: try a tighter start)
        if hi < 4 * lo:
            return None
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        if feasible(u, mid, soil, veh, grid, limits, max_slip)[0]:
            hi = mid
        else:
            lo = mid
    return hi


def margin_cli(vpath: str, terrain: str, R: float, u: float) -> tuple[int, dict]:
    """``soiltrack margin --turn-radius`` as a user runs it: exit code and the JSON."""
    cmd = [sys.executable, "-m", "soiltrack", "margin", "--vehicle", vpath, "--terrain", terrain,
           "--turn-radius", repr(R), "--speed", repr(u), "--json"]  # fmt: skip
    p = subprocess.run(cmd, capture_output=True, text=True)
    try:
        return p.returncode, json.loads(p.stdout)
    except json.JSONDecodeError:
        return p.returncode, {"stderr": p.stderr[-300:]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=float, nargs="+", default=[2.0, 4.0], help="forward speeds, m/s")
    ap.add_argument("--soils", nargs="+", default=["lete_sand", "clayey_soil", "dry_sand"], choices=sorted(ti.SOILS))
    ap.add_argument("--delta", type=float, default=0.03, help="relative distance from the limit checked (3 %%)")
    ap.add_argument("--grid", type=int, nargs=3, default=[100, 6, 100], help="independent nx ny nt")
    ap.add_argument("--max-slip", type=float, default=0.2)
    a = ap.parse_args(argv)
    tv = ti.Vehicle()
    veh = (tv.mass, tv.length, tv.width, tv.tread, tv.radius, tv.mu_r, tv.cg_height)
    limits = (tv.max_torque, 2 * tv.max_power)  # per sprocket torque; power of both
    d = tempfile.mkdtemp(prefix="turn_margin_")
    vpath = os.path.join(d, "vehicle.json")
    ti.write_vehicle(tv, vpath)
    bad = 0
    for name in a.soils:
        s = ti.SOILS[name]
        soil = (s.c, math.radians(s.phi_deg), s.K)
        for u in a.speeds:
            R = limit_radius(u, soil, veh, a.grid, limits, a.max_slip)
            if R is None:
                print(f"{name} {u:g} m/s: no feasible turn up to 60 m (independent)")
                continue
            why = feasible(u, R * (1 - 1e-3), soil, veh, a.grid, limits, a.max_slip)[1]
            print(f"{name} {u:g} m/s: independent limit radius {R:.3f} m (binding just inside: {why})")
            for side in (1.0, -1.0):
                for f, want in ((1 + a.delta, True), (1 - a.delta, False)):
                    rc, out = margin_cli(vpath, name, side * R * f, u)
                    got = out.get("turn_feasible")
                    right = got is want and rc == (0 if want else 1)
                    bad += not right
                    print(f"   R {side * R * f:+8.3f} m: margin says feasible={got} (exit {rc}, limited by "
                          f"{out.get('turn_limited_by')}, its smallest radius {out.get('min_turn_radius_m')}) "
                          f"{'right' if right else 'WRONG'}")  # fmt: skip
    print(f"{'all verdicts right' if not bad else f'{bad} verdicts wrong'}")
    return 0 if not bad else 1


if __name__ == "__main__":
    raise SystemExit(main())
