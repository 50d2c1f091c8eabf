#!/usr/bin/env python
"""Diagnosis checked on data simulated by INDEPENDENT code, through the command line's JSON.

The sweeps and drive logs here are made with plain numpy, not with ``soiltrack.soilmodel``: the
thrust of Eq. 2 by quadrature of the shear law along the track (Wong's type B law for a
strain-softening soil), the quasi-static drive by bisection for the slip. This is a deliberate
second implementation of the physics - an oracle: a bug shared by the library and its own
simulator cannot hide here. Each case goes through ``python -m soiltrack diagnose FILE
--vehicle examples/data/heavy_vehicle.json --json``, as a new user would run it.

Cases (truth in brackets; "unexplained" where the cause is outside the library):

* sweeps (drawbar pull, 60 slips 0.02-0.7, force noise about 1 % and slip noise 0.001):
  effect-free on LETE-like sand and on a clayey soil [none]; slip sinkage mu_s = 0.12
  [slip_sinkage]; Wong type B strain softening K_r = 0.55, K_w = 2.5 cm [hump_shear]; a 0.06 rad
  grade at two normal loads [grade, or none: a resistance proportional to W is nearly absorbed
  by phi]; a load cell saturating at 80 % of the peak [unexplained]; two logger glitches of +8 and
  -7 kN at rows 18 and 42 [none or unexplained, with the two rows named].
* drive logs (60 s at 20 Hz, speed 0.4-3.8 m/s, encoder, GNSS speed, torque and IMU noise):
  effect-free (2 seeds) [none]; a 0.05 rad grade [grade]; 20 % and 25 % extra mass
  [mass_error]; a 4 % radius error [radius_error]; the vehicle-speed channel 4 samples late
  [unexplained]; a much softer patch from 20 to 35 s [unexplained, with a window bracketing
  20-35 s]; a mildly softer patch (its slip change is below the slip noise) [none is fair]; the
  GNSS speed reading 3 % high [unexplained: it offsets the slip like a radius error but leaves the
  torque arm alone]; two torque glitches of +25 and -18 kN m at rows 301 and 801 [none or
  unexplained, with the two rows named].

Run:  python benchmarks/independent_check.py [--kinds sweep,drive] [--seeds 3] [--torque-hold sample] [--set varied]
It prints one line per case and a summary: right verdicts, confident (> 0.5) wrong names, uniform-soil
logs that claim a change of terrain, and (``--set varied``: drive logs at 10 and 50 Hz, 30 and 120 s, a
stop-and-go profile, doubled noise, other magnitudes, a grade and a mass error at once, a 0.2 s delay at
50 Hz, soft patches elsewhere in longer or faster logs) whether the outside cause is named, whether a
patch's window lies within twice the true one, and whether a named verdict's confidence is its weight.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VEHICLE = os.path.join(ROOT, "examples", "data", "heavy_vehicle.json")
M, L, B, R, MU, I_S, G = 33537.2, 2.8, 0.5, 0.3, 0.05, 500.0, 9.81  # as in heavy_vehicle.json
A = 2 * B * L
W0 = M * G


def shear_a(j, K):
    return 1 - np.exp(-j / K)


def shear_b(j, Kr, Kw):
    return Kr * (1 + (1 / (Kr * (1 - 1 / np.e)) - 1) * np.exp(1 - j / Kw)) * (1 - np.exp(-j / Kw))


def thrust_quadrature(slips, W, c, phi, K, hump=None):
    """Both tracks' thrust: (A c + W tan phi) times the mean of the shear law over the track, by quadrature."""
    x = np.linspace(0, L, 2001)
    out = []
    for s in np.atleast_1d(slips):
        f = shear_a(s * x, K) if hump is None else shear_b(s * x, *hump)
        out.append((A * c + W * np.tan(phi)) * np.trapezoid(f, x) / L)
    return np.array(out)


def sweep_csv(
    path,
    seed,
    c=1300.0,
    phi=np.radians(31.1),
    K=0.012,
    loads=(W0,),
    mu_s=0.0,
    grade=0.0,
    hump=None,
    clip=None,
    glitches=(),
):
    rng = np.random.default_rng(seed)
    rows = []
    for W in loads:
        i = np.linspace(0.02, 0.7, 60)
        Wn = W * np.cos(grade)
        D = thrust_quadrature(i, Wn, c, phi, K, hump) - Wn * (MU + mu_s * i) - W * np.sin(grade)
        if clip is not None:
            D = np.minimum(D, clip * D.max())
        D = D + rng.normal(0, 0.01 * np.abs(D).mean() / 3 + 100, D.size)
        for k, dD in glitches:  # a logger glitch: one reading off by dD
            D[k] += dD
        rows += list(zip(i + rng.normal(0, 0.001, i.size), D, np.full(i.size, W)))
    with open(path, "w") as fh:
        fh.write("slip,drawbar_pull_N,normal_load_N\n")
        fh.writelines(f"{a:.5f},{b:.2f},{w:.1f}\n" for a, b, w in rows)


def _thrust_closed(i, W, c, phi, K):
    X = np.maximum(i, 1e-9) * L / K
    return (A * c + W * np.tan(phi)) * (1 - (1 - np.exp(-X)) / X)


def _slip_for(F, W, c, phi, K):
    lo, hi = np.full_like(F, 1e-9), np.full_like(F, 0.95)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        big = _thrust_closed(mid, W, c, phi, K) > F
        hi, lo = np.where(big, mid, hi), np.where(big, lo, mid)
    return 0.5 * (lo + hi)


def log_csv(
    path,
    seed,
    soil=(1300.0, np.radians(31.1), 0.012),
    grade=0.0,
    mass=0.0,
    patch=None,
    delay=0,
    radius=0.0,
    duration=60.0,
    speed_scale=1.0,
    torque_glitches=(),
    rate=20.0,
    profile="sine",
    noise=1.0,
):
    rng = np.random.default_rng(seed)
    t = np.arange(0, duration, 1.0 / rate)
    if profile == "stop_go":  # from standstill to 3 m/s and back to a stop every 15 s
        v = 1.5 * (1 - np.cos(2 * np.pi * t / 15.0)) + 0.02
    else:
        v = 2.0 + 1.2 * np.sin(2 * np.pi * t / 17) + 0.6 * np.sin(2 * np.pi * t / 6.3 + 1) + 0.4 * t / 60.0
    a = np.gradient(v, t)
    m = M * (1 + mass)
    W = m * G
    F = m * a + W * np.cos(grade) * MU + W * np.sin(grade)
    c, phi, K = (np.full(t.size, x) for x in soil)
    if patch is not None:
        inside = (t >= patch[0]) & (t < patch[1])
        c[inside], phi[inside], K[inside] = patch[2]
    i = _slip_for(F, W * np.cos(grade), c, phi, K)
    w = v / (R * (1 + radius) * (1 - i))
    Ms = R * (1 + radius) * F + I_S * np.gradient(w, t)
    vm = speed_scale * v + rng.normal(0, 0.05 * noise, t.size)
    if delay:
        vm = np.concatenate([np.full(delay, vm[0]), vm[:-delay]])
    wm = w * (1 + rng.normal(0, 0.005 * noise, t.size)) + rng.normal(0, 0.01 * noise, t.size)
    Mm = Ms * (1 + rng.normal(0, 0.01 * noise, t.size)) + rng.normal(0, 100 * noise, t.size)
    for k, dM in torque_glitches:
        Mm[k] += dM
    am = a + rng.normal(0, 0.05 * noise, t.size)
    with open(path, "w") as fh:
        fh.write("time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s,vehicle_accel_m_s2\n")
        fh.writelines(",".join(f"{x:.6g}" for x in row) + "\n" for row in zip(t, Mm, wm, vm, am))


def cases(kinds, seeds):
    out = []
    for s in range(seeds):
        if "sweep" in kinds:
            out += [
                ("sweep", "none", s, {}, {"none"}),
                ("sweep", "none, clayey soil", s, dict(c=4140.0, phi=np.radians(13.0), K=0.006), {"none"}),
                ("sweep", "slip_sinkage 0.12", s, dict(mu_s=0.12), {"slip_sinkage"}),
                ("sweep", "hump_shear (Wong type B)", s, dict(hump=(0.55, 0.025)), {"hump_shear"}),
                ("sweep", "grade 0.06, two loads", s, dict(loads=(W0, 0.6 * W0), grade=0.06), {"grade", "none"}),
                ("sweep", "OUT: load cell saturates", s, dict(clip=0.8), {"unexplained"}),
                (
                    "sweep",
                    "OUT: two glitches (rows 18, 42)",
                    s,
                    dict(glitches=((17, 8000.0), (41, -7000.0))),
                    {"none", "unexplained"},
                ),
            ]
    if "drive" in kinds:
        for s in range(1, 1 + max(1, seeds // 2 + 1)):
            out += [
                ("drive", "none", s, {}, {"none"}),
                ("drive", "grade 0.05", s, dict(grade=0.05), {"grade"}),
                ("drive", "mass_error 0.2", s, dict(mass=0.2), {"mass_error"}),
                ("drive", "radius_error 0.04", s, dict(radius=0.04), {"radius_error"}),
                ("drive", "OUT: speed 4 samples late", s, dict(delay=4), {"unexplained"}),
                (
                    "drive",
                    "OUT: soft patch 20-35 s",
                    s,
                    dict(patch=(20.0, 35.0, (200.0, np.radians(12.0), 0.05))),
                    {"unexplained"},
                ),
                (
                    "drive",
                    "OUT: mild patch 20-35 s",
                    s,
                    dict(patch=(20.0, 35.0, (800.0, np.radians(24.0), 0.03))),
                    {"unexplained", "none"},
                ),
                ("drive", "OUT: GNSS speed reads 3 % high", s, dict(speed_scale=1.03), {"unexplained"}),
                (
                    "drive",
                    "OUT: torque glitches (rows 301, 801)",
                    s,
                    dict(torque_glitches=((300, 25000.0), (800, -18000.0))),
                    {"none", "unexplained"},
                ),
            ]
    return out


def varied_cases(seeds):
    """Drive logs at other rates, durations, driving profiles, noise levels and magnitudes, two effects at
    once, other delays and patches (the ``--set varied`` cases); truth as in :func:`cases`, and for an
    outside cause the cause the JSON should name (``expect_cause``) and a patch's true window."""
    out = []
    patch_soft = (200.0, np.radians(12.0), 0.05)
    for s in range(1, 1 + seeds):
        out += [
            ("drive", "none, 50 Hz, 30 s", s, dict(rate=50.0, duration=30.0), {"none"}),
            (
                "drive",
                "none, 10 Hz, 120 s, stop-and-go",
                s,
                dict(rate=10.0, duration=120.0, profile="stop_go"),
                {"none"},
            ),
            ("drive", "none, noise x2", s, dict(noise=2.0), {"none"}),
            ("drive", "grade 0.08, stop-and-go", s, dict(grade=0.08, profile="stop_go"), {"grade"}),
            ("drive", "mass_error 0.1, 50 Hz", s, dict(mass=0.1, rate=50.0), {"mass_error"}),
            ("drive", "radius_error 0.03, noise x2", s, dict(radius=0.03, noise=2.0), {"radius_error"}),
            ("drive", "grade 0.05 + mass_error 0.2", s, dict(grade=0.05, mass=0.2), {"grade", "mass_error"}),
            ("drive", "OUT: speed 0.2 s late, 50 Hz", s, dict(delay=10, rate=50.0), {"unexplained"}, "delay"),
            (
                "drive",
                "OUT: soft patch 70-90 s, 120 s",
                s,
                dict(duration=120.0, patch=(70.0, 90.0, patch_soft)),
                {"unexplained"},
                "terrain_change",
                (70.0, 90.0),
            ),
            (
                "drive",
                "OUT: soft patch 10-25 s, 50 Hz",
                s,
                dict(rate=50.0, patch=(10.0, 25.0, patch_soft)),
                {"unexplained"},
                "terrain_change",
                (10.0, 25.0),
            ),
        ]
    return out


def _within_twice(window, true):
    """Whether a reported window lies inside the true window widened by half its length on each side (twice
    its length, centred on it)."""
    half = 0.5 * (true[1] - true[0])
    return bool(window) and true[0] - half <= window[0] < window[1] <= true[1] + half


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kinds", default="sweep,drive")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument(
        "--set",
        choices=("standard", "varied"),
        default="standard",
        help="standard: the cases above; varied: drive logs at other rates, durations, profiles, noise "
        "levels and magnitudes, two effects at once, other delays and patches (checks the cause, the "
        "window within twice the true one, no change of terrain on uniform soil, confidence = weight)",
    )
    ap.add_argument(
        "--torque-hold",
        choices=("zoh", "sample"),
        default=None,
        help="passed to the drive-log diagnoses (these logs sample a continuous torque: 'sample' "
        "describes them; default: the library's default, zoh)",
    )
    args = ap.parse_args(argv)
    kinds = set(args.kinds.split(","))
    right = confident_wrong = total = 0
    checks = {"cause named": [0, 0], "window within twice": [0, 0], "confidence = weight": [0, 0]}
    uniform_terrain = uniform = 0
    todo = cases(kinds, args.seeds) if args.set == "standard" else varied_cases(args.seeds)
    with tempfile.TemporaryDirectory() as tmp:
        for kind, label, seed, kw, truth, *expect in todo:
            path = os.path.join(tmp, f"{kind}_{seed}.csv")
            (sweep_csv if kind == "sweep" else log_csv)(path, seed, **kw)
            t0 = time.perf_counter()
            hold = ["--torque-hold", args.torque_hold] if kind == "drive" and args.torque_hold else []
            p = subprocess.run(
                [sys.executable, "-m", "soiltrack", "diagnose", path, "--vehicle", VEHICLE, "--json", *hold],
                cwd=ROOT,
                capture_output=True,
                text=True,
            )
            dt = time.perf_counter() - t0
            total += 1
            try:
                j = json.loads(p.stdout)
            except json.JSONDecodeError:
                print(f"{kind:5s} {label:28s} seed {seed}: exit {p.returncode}, no JSON: {p.stderr.strip()[-200:]}")
                continue
            ok = j["verdict"] in truth
            wrong = not ok and j["verdict"] not in ("none", "unexplained") and j["confidence"] > 0.5
            right += ok
            confident_wrong += wrong
            if kind == "drive" and "patch" not in kw:
                uniform += 1
                uniform_terrain += j.get("cause") == "terrain_change"
            if expect:
                checks["cause named"][0] += j.get("cause") == expect[0]
                checks["cause named"][1] += 1
            if len(expect) > 1:
                checks["window within twice"][0] += _within_twice(j.get("window_s"), expect[1])
                checks["window within twice"][1] += 1
            if j["verdict"] not in ("none", "unexplained"):
                w = next((r["weight"] for r in j["ranking"] if r["effect"] == j["verdict"]), None)
                checks["confidence = weight"][0] += w is not None and abs(w - j["confidence"]) < 1e-9
                checks["confidence = weight"][1] += 1
            extra = f"  cause {j.get('cause')}" if j.get("cause") else ""
            if j.get("window_s"):
                extra += f"  window {j['window_s'][0]:.1f}-{j['window_s'][1]:.1f} s"
            if j.get("lag_s") is not None:
                extra += f"  lag {j['lag_s']:.3g} s"
            shrink = j.get("shrink")
            print(
                f"{kind:5s} {label:28s} seed {seed}: {j['verdict']:20s} confidence {j['confidence']:.2f}  "
                f"shrink {'-' if shrink is None else f'{shrink:.2f}'}  exit {p.returncode}  {dt:5.1f} s"
                f"{'  RIGHT' if ok else ('  CONFIDENT WRONG' if wrong else '')}{extra}",
                flush=True,
            )
    print(f"\n{right}/{total} right; {confident_wrong} confident (> 0.5) wrong names")
    print(f"uniform-soil drive logs that claim a change of terrain: {uniform_terrain}/{uniform}")
    for name, (k, n) in checks.items():
        if n:
            print(f"{name}: {k}/{n}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
