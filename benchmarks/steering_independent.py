"""Steady turns: the library's steering model against an independent numpy model (acceptance, issue 42).

The independent model (written apart from soilmodel.steering, numpy only): each point of each
track's contact patch (a midpoint grid of ``--nx`` x ``--ny`` cells) slides over the ground with the
hull-frame velocity ``(u - Om y - r w_k, v + Om x)``; its shear displacement is that sliding velocity
integrated NUMERICALLY along the point's path since its entry at the front (``--nt`` trapezoid steps,
each rotated into the ground frame by the hull's heading change ``Om tau``) - no closed form;
Janosi-Hanamoto shear ``(c + p tan phi)(1 - exp(-|j|/K))`` along the current sliding direction, uniform
pressure per track with the lateral load transfer ``m u Om h / B``, rolling resistance ``mu_r W_k``
along each track. The steady balances ``X = -m v Om``, ``Y = m u Om``, ``N = 0`` are solved by
Newton with a finite-difference Jacobian. Compared: turning radius and both sprocket torques for
several sprocket-speed ratios on three soils (acceptance: within 5 %).

    python benchmarks/steering_independent.py
    python benchmarks/steering_independent.py --nx 120 --ny 8 --nt 120
"""

from __future__ import annotations

import argparse
import dataclasses
import math


def _forces(np, z, wl, wr, soil, veh, nx, ny, nt):
    """(X, Y, N, Fx_left, Fx_right) of the independent model at z = (u, v, Om)."""
    u, v, Om = z
    c, phi, K = soil
    m, l, b, B, r, mu_r, h = veh
    g = 9.81
    W = m * g
    dW = m * u * Om * h / B
    out = []
    xs = l / 2 - (np.arange(nx) + 0.5) * l / nx  # cell centres, front to rear
    for belt, yc, Wk in ((r * wl, B / 2, W / 2 - dW), (r * wr, -B / 2, W / 2 + dW)):
        ys = yc - b / 2 + (np.arange(ny) + 0.5) * b / ny
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        T = (l / 2 - X) / belt  # time since entry
        s = np.linspace(0.0, 1.0, nt + 1)  # path parameter: tau = s T
        tau = T[..., None] * s
        xp = l / 2 - belt * tau  # the point's position along the track at tau (hull frame)
        vx = u - Om * Y[..., None] - belt
        vy = v + Om * xp
        ang = -Om * (T[..., None] - tau)  # rotate each past velocity into the current hull frame
        gx = vx * np.cos(ang) - vy * np.sin(ang)
        gy = vx * np.sin(ang) + vy * np.cos(ang)
        wts = np.full(nt + 1, 1.0 / nt)
        wts[[0, -1]] *= 0.5
        jx = (gx * wts).sum(-1) * T
        jy = (gy * wts).sum(-1) * T
        j = np.hypot(jx, jy)
        p = Wk / (b * l)
        tau_s = (c + p * math.tan(phi)) * (1 - np.exp(-j / K))
        Vx, Vy = u - Om * Y - belt, v + Om * X
        sp = np.sqrt(Vx**2 + Vy**2 + 1e-12)
        dA = (l / nx) * (b / ny)
        fx, fy = -tau_s * Vx / sp * dA, -tau_s * Vy / sp * dA
        R = mu_r * Wk
        out.append((fx.sum(), fy.sum(), (X * fy - Y * fx).sum(), R, yc))
    (fxl, fyl, ml, Rl, yl), (fxr, fyr, mr, Rr, yr) = out
    return fxl + fxr - Rl - Rr, fyl + fyr, ml + mr + yl * Rl + yr * Rr, fxl, fxr


def solve(np, wl, wr, soil, veh, z0, nx, ny, nt):
    """Newton (finite-difference Jacobian) on the steady balances; (u, v, Om, Fx_l, Fx_r, residual)."""
    m, l = veh[0], veh[1]
    W = m * 9.81

    def res(z):
        X, Y, N, *_ = _forces(np, z, wl, wr, soil, veh, nx, ny, nt)
        return np.array([(X + m * z[1] * z[2]) / W, (Y - m * z[0] * z[2]) / W, N / (W * l)])

    z = np.array(z0, dtype=float)
    for _ in range(40):
        f = res(z)
        if np.max(np.abs(f)) < 1e-11:
            break
        J = np.empty((3, 3))
        for k in range(3):
            dz = np.zeros(3)
            dz[k] = 1e-7 * max(1.0, abs(z[k]))
            J[:, k] = (res(z + dz) - f) / dz[k]
        step = np.linalg.solve(J, -f)
        lam = 1.0
        while lam > 1e-4 and np.max(np.abs(res(z + lam * step))) >= np.max(np.abs(f)):
            lam *= 0.5
        z = z + lam * step
    _X, _Y, _N, fxl, fxr = _forces(np, z, wl, wr, soil, veh, nx, ny, nt)
    return z, fxl, fxr, float(np.max(np.abs(res(z))))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nx", type=int, default=160, help="cells along each patch (default 160)")
    ap.add_argument("--ny", type=int, default=8, help="cells across each patch (default 8)")
    ap.add_argument("--nt", type=int, default=160, help="trapezoid steps along each point's path (default 160)")
    ap.add_argument("--tol", type=float, default=0.05, help="acceptance: largest relative difference (default 0.05)")
    a = ap.parse_args(argv)
    import numpy as np

    from soiltrack.soilmodel import TERRAINS, VEHICLES
    from soiltrack.soilmodel.steering import steady_turn

    veh_obj = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.0)
    v = veh_obj
    veh = (v.mass, v.track_length, v.track_width, v.tread, v.sprocket_radius, v.rolling_resistance, v.cg_height)
    worst = 0.0
    print(f"vehicle heavy (tread 2.5 m, cg 1 m); independent grid {a.nx} x {a.ny}, {a.nt} path steps")
    print(f"{'soil':12s} {'wr/wl':>6s} {'R lib':>9s} {'R ind':>9s} {'dR %':>7s} {'Tl lib':>9s} {'dTl %':>7s} "
          f"{'Tr lib':>9s} {'dTr %':>7s}")  # fmt: skip
    for name in ("lete_sand", "clayey_soil", "dry_sand"):
        s = TERRAINS[name]
        sv = (s.cohesion, s.friction_angle, s.shear_modulus)
        for ratio in (1.05, 1.1, 1.2, 1.4, 1.8):
            wl, wr = 5.0, 5.0 * ratio
            t = steady_turn(wl, wr, s, veh_obj)
            z0 = (t.forward_speed * 1.02, 0.0, t.yaw_rate * 0.95)  # near, not at, the library's answer
            z, fxl, fxr, res = solve(np, wl, wr, sv, veh, z0, a.nx, a.ny, a.nt)
            R_ind = math.hypot(z[0], z[1]) / z[2]
            Tl, Tr = v.sprocket_radius * fxl, v.sprocket_radius * fxr
            d = [(t.radius / R_ind - 1), (t.torque_left / Tl - 1), (t.torque_right / Tr - 1)]
            worst = max(worst, *map(abs, d))
            flag = "" if t.converged and res < 1e-8 else "  (not converged)"
            print(f"{name:12s} {ratio:6.2f} {t.radius:9.3f} {R_ind:9.3f} {100 * d[0]:7.3f} {t.torque_left:9.0f} "
                  f"{100 * d[1]:7.3f} {t.torque_right:9.0f} {100 * d[2]:7.3f}{flag}")  # fmt: skip
    ok = worst <= a.tol
    print(f"largest relative difference {100 * worst:.3f} % ({'within' if ok else 'OUTSIDE'} {100 * a.tol:g} %)")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
