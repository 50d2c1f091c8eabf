"""On-line estimator against the alternatives a user would script, on simulated logs (one run).

Per-update time (wall clock and this thread's CPU time, median and p99) of

- ``OnlineEstimator.update`` (moving horizon, one Newton step per sample, compiled kernels);
- refitting ``soiltrack.identify.fit`` on the sliding window at every sample (IPOPT with
  multistart, the batch estimator), timed on a subsample of the updates;
- an IPOPT moving-horizon re-solve of the same window warm-started from the previous
  solution (what a generic MHE does: the window's output-error NLP in CasADi, solved to
  convergence at every sample), timed on a subsample of the updates;

accuracy against the truth over time, detection delay of a change of terrain and false alarms
per hour on uniform soil, at 10, 50 and 100 Hz.

The logs come from the library's simulator (:func:`soiltrack.soilmodel.simulate_drive_log`,
CVODES closed loop): the light vehicle climbing a 20 deg slope (a steady thrust of about 40 %
of the soil's limit) with a hard acceleration every 4 s, LETE sand, switching to snow at
31 s (``soil_changes``). The uniform-soil logs for false alarms are 10-minute runs of the same
driving and of the library's default profile (mostly gentle), on several seeds.

The default run (issue 38) compares, side by side on the same logs of an independent simulator
(``tests/online_oracle.py``), this estimator, the window estimator of before, a sliding-window
refit with ``fit``, an EKF on (F_max, K) and a recursive Bayes filter over a terrain bank
(``online_compare.py``)::

    python benchmarks/bench_online.py --size small --estimators held,window,ekf,bank
    python benchmarks/bench_online.py --size medium            # all five, 24 change logs
    python benchmarks/bench_online.py --timing                 # the timing study of issue 22 (10 minutes)
    python benchmarks/bench_online.py --timing --quick         # one rate, shorter false-alarm logs
    python benchmarks/bench_online.py --set tuning             # the detector's tuning set (held only)
    python benchmarks/bench_online.py --set heldout            # ... its held-out set (report only)
    python benchmarks/bench_online.py --slope                  # the known grade, with and without (about 30 s)
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from soiltrack.identify import OnlineEstimator, OnlineSettings, fit
from soiltrack.soilmodel import TERRAINS, VEHICLES, DriveLog, max_thrust, simulate_drive_log

#: The change of terrain of the change logs, s.
CHANGE_TIME_S = 31.0
#: Grade of the change logs, deg (a steady thrust: the soil's curve is visible while cruising).
GRADE_DEG = 20.0
#: Window of the estimator and of the alternatives, s.
WINDOW_S = 5.0


def climb_profile(t):
    """Speed reference: 1 m/s, stepped to 2 m/s every 4 s for 2 s (hard accelerations)."""
    ph = np.mod(t, 4.0)
    return np.where(t < 0.5, 0.0, np.where(ph < 2.0, 1.0, 2.0))


def change_log(rate_hz: float, seed: int, duration_s: float = 60.0, change: bool = True):
    """Light vehicle climbing, LETE sand -> snow at :data:`CHANGE_TIME_S` (or uniform); log and truth."""
    veh = VEHICLES["light"]
    th = math.radians(GRADE_DEG)
    changes = [(CHANGE_TIME_S, TERRAINS["snow"])] if change else []
    log, truth = simulate_drive_log(
        veh,
        TERRAINS["lete_sand"],
        seed=seed,
        duration_s=duration_s,
        sample_rate_hz=rate_hz,
        speed_profile=climb_profile,
        effects={"grade": th},
        soil_changes=changes,
        return_truth=True,
    )
    W = veh.weight * math.cos(th)
    F = np.array(
        [
            max_thrust(TERRAINS["lete_sand"], veh, normal_load=W),
            max_thrust(TERRAINS["snow"], veh, normal_load=W),
        ]
    )
    truth["max_thrust"] = F[truth.get("soil_index", np.zeros(log.n_samples, dtype=int))]
    return log, truth


def two_track(
    log: DriveLog,
    turns,
    seed: int = 0,
    steer_torque_frac: float = 0.3,
    turn_speed_frac: float = 0.15,
    track_gauge_m: float = 0.4,
    r: float = 0.08,
) -> dict:
    """A two-track view of a straight log: per-track torque and speed, turns with a yaw rate.

    Outside ``turns`` (``[(t0, t1), ...]``) the torque splits evenly and both sprockets turn
    at the logged speed (each with its own encoder noise of the log's size); inside, the
    speeds part by ``+- turn_speed_frac`` of the speed and both torques grow by
    ``steer_torque_frac`` (the steering resistance a straight-line model does not know:
    fitted, these samples would read as a stronger soil). Returns the CSV columns.
    """
    rng = np.random.default_rng(seed)
    t, M, w = log.time, log.sprocket_torque, log.sprocket_speed
    turning = np.zeros(t.size, dtype=bool)
    for t0, t1 in turns:
        turning |= (t >= t0) & (t <= t1)
    d = np.where(turning, turn_speed_frac * np.abs(w), 0.0)
    s_w = 0.002
    wl = w + d + s_w * rng.standard_normal(t.size)
    wr = w - d + s_w * rng.standard_normal(t.size)
    extra = np.where(turning, steer_torque_frac * np.abs(M), 0.0)
    ml = 0.5 * M + 0.5 * extra
    mr = 0.5 * M + 0.5 * extra
    yaw = (wl - wr) * r / track_gauge_m + 0.002 * rng.standard_normal(t.size)
    return {
        "time_s": t,
        "sprocket_torque_left_Nm": ml,
        "sprocket_torque_right_Nm": mr,
        "sprocket_speed_left_rad_s": wl,
        "sprocket_speed_right_rad_s": wr,
        "vehicle_speed_m_s": log.vehicle_speed,
        "yaw_rate_rad_s": yaw,
        "_turning": turning,
    }


def replay(log: DriveLog, vehicle, settings: OnlineSettings | None = None):
    """Estimates of every update, wall and CPU time per update, and the estimator."""
    est = OnlineEstimator(vehicle, settings or OnlineSettings(window_s=WINDOW_S))
    rows = list(
        zip(
            log.time.tolist(),
            log.sprocket_torque.tolist(),
            log.sprocket_speed.tolist(),
            log.vehicle_speed.tolist(),
        )
    )
    wall, cpu, out = np.empty(len(rows)), np.empty(len(rows)), []
    for k, row in enumerate(rows):
        c0, t0 = time.thread_time_ns(), time.perf_counter_ns()
        e = est.update(*row)
        wall[k] = (time.perf_counter_ns() - t0) * 1e-9
        cpu[k] = (time.thread_time_ns() - c0) * 1e-9
        out.append(e)
    return out, wall, cpu, est


def window_rows(log: DriveLog, k: int) -> slice:
    """Rows of the batch fit of the window ending at sample ``k`` (and the sample before it)."""
    k0 = int(np.searchsorted(log.time, log.time[k] - WINDOW_S)) - 1
    return slice(max(k0, 0), k + 1)


def batch_refit_times(log: DriveLog, vehicle, ks) -> np.ndarray:
    """Wall time of ``fit`` on the sliding window at the samples ``ks``."""
    out = []
    for k in ks:
        t0 = time.perf_counter()
        fit(log.subset(window_rows(log, k)), vehicle)
        out.append(time.perf_counter() - t0)
    return np.array(out)


def mhe_resolve_times(log: DriveLog, vehicle, ks) -> np.ndarray:
    """Wall time of an IPOPT moving-horizon re-solve of the window at the samples ``ks``.

    The window's output-error NLP (F_max, K and one latent slip per sample, the batch fit's
    residuals and noise weights) built once for the window's size with the data as
    parameters, warm-started from the previous solution and solved to IPOPT's tolerance.
    """
    import casadi as ca

    from soiltrack.identify.drivelog.prepare import prepare_drive_log
    from soiltrack.soilmodel.traction import slip_factor

    r, l = vehicle.sprocket_radius, vehicle.track_length
    out, solver, n_built, x0 = [], None, None, None
    for k in ks:
        prep = prepare_drive_log(log.subset(window_rows(log, k)), vehicle)
        n = prep.n_used
        t0 = time.perf_counter()
        if solver is None or n != n_built:
            x = ca.SX.sym("x", 2 + n)
            p = ca.SX.sym("p", 6 * n)
            v, w, T, iss, isc, rho = (p[j * n : (j + 1) * n] for j in range(6))
            Fm, K, i = x[0] * 1e2, x[1] * 1e-2, x[2:]
            d_s = v - r * w * (1 - i)
            e_w = d_s * iss
            e_T = (T - Fm * slip_factor(i, l, K) - rho * d_s) * isc
            solver = ca.nlpsol(
                "mhe",
                "ipopt",
                {"x": x, "p": p, "f": 0.5 * (ca.sumsqr(e_w) + ca.sumsqr(e_T))},
                {
                    "print_time": False,
                    "ipopt.print_level": 0,
                    "ipopt.sb": "yes",
                    "ipopt.warm_start_init_point": "yes",
                },
            )
            n_built = n
            x0 = np.concatenate([[3.0, 1.2], np.clip(prep.slip_measured, 0.0, 0.9)])
        pv = np.concatenate(
            [
                prep.vehicle_speed,
                prep.sprocket_speed,
                prep.thrust,
                1 / prep.sigma_speed,
                1 / prep.sigma_thrust_cond,
                prep.coupling,
            ]
        )
        lb = np.concatenate([[0.3, 0.6], np.full(n, -0.95)])
        ub = np.concatenate([[72.0, 5.0], np.full(n, 0.98)])
        sol = solver(x0=x0, p=pv, lbx=lb, ubx=ub)
        x0 = np.asarray(sol["x"]).ravel()
        out.append(time.perf_counter() - t0)
    return np.array(out)


def detection(estimates, truth, rate_hz: float) -> dict:
    """Delay of the first detection after the change, false alarms, and accuracy of F_max after it."""
    det = [(e.time_s, e.change_time_s) for e in estimates if e.change_detected]
    after = [d for d in det if d[0] >= CHANGE_TIME_S]
    false = [d for d in det if d[0] < CHANGE_TIME_S]
    t = np.array([e.time_s for e in estimates])
    F = np.array([np.nan if e.max_thrust_stderr_N is None else e.max_thrust_N for e in estimates])
    F_true = truth["max_thrust"]
    within = np.abs(F - F_true) <= 0.05 * F_true
    # first time after the change from which F_max is identified and within 5 % for good (to the end)
    post = t > CHANGE_TIME_S + 0.5 / rate_hz  # the first sample on the new soil on
    bad = post & ~within
    settle = (
        float(t[np.nonzero(bad)[0][-1] + 1] - CHANGE_TIME_S)
        if bad.any() and np.nonzero(bad)[0][-1] + 1 < t.size
        else (0.0 if not bad.any() else math.inf)
    )
    first_ok = post & within
    return {
        "delay_s": after[0][0] - CHANGE_TIME_S if after else math.inf,
        "dated_s": after[0][1] if after else math.nan,
        "extra_alarms": len(after) - 1 if after else 0,
        "false_before": len(false),
        "first_within_5pct_s": float(t[np.nonzero(first_ok)[0][0]] - CHANGE_TIME_S) if first_ok.any() else math.inf,
        "within_5pct_for_good_s": settle,
        "share_identified_within_5pct_before": float(np.mean(within[(t > 10) & (t < CHANGE_TIME_S) & np.isfinite(F)])),
    }


#: The slope logs: grade (deg), and the low and high speeds of the pulls (m/s).
SLOPE_LOGS = ((10.0, 1.0, 2.0), (8.0, 1.0, 2.5))


def slope_profile(low: float, high: float):
    """Speed reference: ``low`` m/s, stepped to ``high`` every 4 s for 2 s (pulls near the traction limit)."""
    return lambda t: np.where(t < 0.5, 0.0, np.where(np.mod(t, 4.0) < 2.0, low, high))


def slope_study(seeds=(5, 6, 7)) -> None:
    """On-line estimates on a grade with the grade given and without; batch fit of the same window."""
    for deg, low, high in SLOPE_LOGS:
        _slope_logs(deg, low, high, seeds)
    veh, soil = VEHICLES["light"], TERRAINS["lete_sand"]
    deg, _, high = SLOPE_LOGS[-1]
    th = math.radians(deg)
    print(f"uniform soil, {deg:g} deg, pulls from 0.5 m/s to {high:g} m/s (every alarm is false):")
    for seed in seeds:
        log = simulate_drive_log(
            veh,
            soil,
            seed=seed,
            duration_s=30.0,
            sample_rate_hz=50.0,
            speed_profile=slope_profile(0.5, high),
            effects={"grade": th},
            controller_bandwidth=2.0,
        )
        _, _, _, est = replay(log, veh, OnlineSettings(window_s=WINDOW_S, grade_rad=th))
        at = [round(c["detected_at_s"], 2) for c in est.changes]
        print(f"  seed {seed}: {len(est.changes)} alarms in 30 s at {at} s")


def _slope_logs(deg: float, low: float, high: float, seeds) -> None:
    veh, soil = VEHICLES["light"], TERRAINS["lete_sand"]
    th = math.radians(deg)
    N = veh.weight * math.cos(th)
    F_N, F_W = max_thrust(soil, veh, normal_load=N), max_thrust(soil, veh, normal_load=veh.weight)
    print(
        f"light vehicle on LETE sand, {deg:g} deg grade, 30 s at 50 Hz, pulls {low:g} -> {high:g} m/s; "
        f"truth F_max = {F_N:.1f} N at N = W cos(theta) = {N:.1f} N ({F_W:.1f} N at W = {veh.weight:.0f} N), "
        f"K = {1e3 * soil.shear_modulus:.1f} mm"
    )
    for seed in seeds:
        log = simulate_drive_log(
            veh,
            soil,
            seed=seed,
            duration_s=30.0,
            sample_rate_hz=50.0,
            speed_profile=slope_profile(low, high),
            effects={"grade": th},
            controller_bandwidth=2.0,
        )
        res = {}
        for label, g in (("given", th), ("not given", 0.0)):
            out, _, _, est = replay(log, veh, OnlineSettings(window_s=WINDOW_S, grade_rad=g))
            res[label] = (out[-1], len(est.changes))
        e, f = res["given"][0], res["not given"][0]
        b = fit(log.subset(window_rows(log, log.n_samples - 1)), veh).extra
        sF = e.max_thrust_stderr_N or math.nan
        sK = e.shear_modulus_stderr_m or math.nan
        print(
            f"  seed {seed}: grade given: N = {e.normal_load_N:.1f} N, F_max {e.max_thrust_N:.1f} +- {sF:.1f} N "
            f"({100 * (e.max_thrust_N / F_N - 1):+.1f} % of the truth at N, {(e.max_thrust_N - F_N) / sF:+.2f} SE), "
            f"K {1e3 * e.shear_modulus_m:.2f} +- {1e3 * sK:.2f} mm "
            f"({(e.shear_modulus_m - soil.shear_modulus) / sK:+.2f} SE), {res['given'][1]} alarms; "
            f"batch fit of the window F_max {b['max_thrust_N']:.1f} +- {b['max_thrust_stderr_N']:.1f} N"
        )
        print(
            f"           not given: N = {f.normal_load_N:.1f} N, F_max {f.max_thrust_N:.1f} N "
            f"(differs by {abs(f.max_thrust_N - e.max_thrust_N):.1e} N), K differs by "
            f"{abs(f.shear_modulus_m - e.shear_modulus_m):.1e} m; read as F_max at W it is "
            f"{100 * (f.max_thrust_N / F_W - 1):+.1f} % off the truth at W (the load is attributed wrongly, "
            f"by {F_W - F_N:.1f} N = (W - N) tan(phi))"
        )


def _run_set(a, names) -> None:
    """``--set``: the detector's fixed log sets (``online_sets.py``), the held estimator unless ``--estimators``."""
    import online_sets

    over: dict = {}
    for kv in a.setting:
        k, _, v = kv.partition("=")
        over[k] = int(v) if v.lstrip("-").isdigit() else float(v)
    online_sets.run_set(a.set, names if a.estimators_given else ("held",), only=a.only, overrides=over)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--size",
        choices=("small", "medium", "full"),
        default="small",
        help="comparison: logs (small: 8 change logs a vehicle)",
    )
    ap.add_argument(
        "--estimators", default="held,window,refit,ekf,bank", help="comparison: which estimators, comma-separated"
    )
    ap.add_argument("--duration", type=float, default=120.0, help="comparison: length of each change log, s")
    ap.add_argument("--uniform-s", type=float, default=600.0, help="comparison: length of each uniform-soil log, s")
    ap.add_argument("--logs", type=int, default=None, help="comparison: only the first N change logs")
    ap.add_argument(
        "--set",
        choices=("tuning", "heldout"),
        default=None,
        help="the detector's fixed log sets (online_sets.py): 36 change logs and one uniform hour each",
    )
    ap.add_argument(
        "--setting", action="append", default=[], metavar="NAME=VALUE", help="with --set: an OnlineSettings value"
    )
    ap.add_argument("--only", default=None, help="with --set: only the logs whose label contains this text")
    ap.add_argument("--timing", action="store_true", help="the timing study of issue 22 instead of the comparison")
    ap.add_argument("--quick", action="store_true", help="with --timing: 50 Hz only, 2 x 5-minute false-alarm logs")
    ap.add_argument("--slope", action="store_true", help="only the known-grade study (8 deg, with and without)")
    a = ap.parse_args(argv)
    a.estimators_given = any(x.startswith("--estimators") for x in (argv if argv is not None else sys.argv[1:]))
    if a.slope:
        slope_study()
        return 0
    if not a.timing:
        import online_compare

        names = tuple(x.strip() for x in a.estimators.split(",") if x.strip())
        bad = [n for n in names if n not in online_compare.ESTIMATORS]
        if bad:
            ap.error(f"--estimators: unknown {bad}; choose from {list(online_compare.ESTIMATORS)}")
        print("machine load (1-min average) at the start:", open("/proc/loadavg").read().split()[0])
        if a.set:
            _run_set(a, names)
            return 0
        online_compare.compare(a.size, names, a.duration, a.uniform_s, logs=a.logs)
        return 0
    veh = VEHICLES["light"]
    rates = (50.0,) if a.quick else (10.0, 50.0, 100.0)
    print(f"light vehicle, {GRADE_DEG:g} deg climb, LETE sand -> snow at {CHANGE_TIME_S:g} s, window {WINDOW_S:g} s")
    print(
        "machine load (1-min average) at the start:",
        open("/proc/loadavg").read().split()[0],
        "on",
        __import__("os").cpu_count(),
        "cores",
    )
    for rate in rates:
        log, truth = change_log(rate, seed=11)
        est_list, wall, cpu, est = replay(log, veh)
        det = detection(est_list, truth, rate)
        dt = 1.0 / rate
        print(f"\n--- {rate:g} Hz ({log.n_samples} samples, kernels: {est.backend})")
        print(
            f"online update: wall median {1e6 * np.median(wall):.0f} us, "
            f"p99 {1e6 * np.quantile(wall, 0.99):.0f} us;"
            f" CPU median {1e6 * np.median(cpu):.0f} us, p99 {1e6 * np.quantile(cpu, 0.99):.0f} us; "
            f"{dt / np.median(wall):.0f} x faster than real time (median wall), "
            f"{log.time[-1] / wall.sum():.0f} x over the whole replay"
        )
        print(
            f"change: detected {det['delay_s']:.2f} s after it (dated {det['dated_s']:.2f} s), "
            f"{det['extra_alarms']} further alarms after it, {det['false_before']} before it; "
            f"F_max identified and within 5 % {det['first_within_5pct_s']:.2f} s after it, "
            f"for good from {det['within_5pct_for_good_s']:.2f} s; "
            f"before it, {100 * det['share_identified_within_5pct_before']:.0f} % of the identified "
            f"estimates "
            f"(10-31 s) within 5 % of the truth"
        )
        for tq in (20.0, 30.0, 36.0, 45.0, 59.0):
            e = est_list[int(round(tq * rate))]
            Ft = truth["max_thrust"][int(round(tq * rate))]
            print(
                f"  t = {tq:4.0f} s: F_max {e.max_thrust_N:.1f} N"
                + (f" +- {e.max_thrust_stderr_N:.1f}" if e.max_thrust_stderr_N else " (not identifiable)")
                + f" (truth {Ft:.1f}, error {100 * (e.max_thrust_N / Ft - 1):+.1f} %), "
                f"K {1e3 * e.shear_modulus_m:.1f} mm, "
                f"identifiable {e.identifiable}"
            )
        n_sub = 20 if a.quick else 40
        ks = np.linspace(int(8 * rate), log.n_samples - 1, n_sub).astype(int)
        bt = batch_refit_times(log, veh, ks)
        mt = mhe_resolve_times(log, veh, np.arange(int(40 * rate), int(40 * rate) + n_sub))
        print(
            f"refit `fit` on the window (subsample of {ks.size} updates): "
            f"median {1e3 * np.median(bt):.1f} ms, p99 {1e3 * np.quantile(bt, 0.99):.1f} ms = "
            f"{np.median(bt) / np.median(wall):.0f} x the online update"
        )
        print(
            f"IPOPT moving-horizon re-solve, warm start ({n_sub} consecutive updates): median "
            f"{1e3 * np.median(mt):.1f} ms, p99 {1e3 * np.quantile(mt, 0.99):.1f} ms = "
            f"{np.median(mt) / np.median(wall):.0f} x the online update"
        )
    # false alarms on uniform soil
    minutes = 5.0 if a.quick else 10.0
    seeds = (21, 22) if a.quick else (21, 22, 23)
    total_h, alarms = 0.0, 0
    print(f"\n--- false alarms on uniform soil ({minutes:g}-minute logs, 50 Hz)")
    for seed in seeds:
        for kind in ("climb", "default"):
            if kind == "climb":
                log, _ = change_log(50.0, seed, duration_s=60.0 * minutes, change=False)
                vv = veh
            else:
                vv = VEHICLES["heavy" if seed % 2 else "light"]
                log = simulate_drive_log(vv, TERRAINS["lete_sand"], seed=seed, duration_s=60.0 * minutes)
            est_list, wall, cpu, est = replay(log, vv)
            n = len(est.changes)
            alarms += n
            total_h += log.time[-1] / 3600.0
            print(f"  seed {seed}, {kind} profile ({vv.name or 'vehicle'}): {n} alarms in {log.time[-1] / 60:.0f} min")
    print(f"false alarms: {alarms} in {total_h:.2f} h = {alarms / total_h:.2f} per hour")
    return 0


if __name__ == "__main__":
    sys.exit(main())
