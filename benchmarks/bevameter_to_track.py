"""Bevameter tests simulated by plain numpy (not soilmodel), fitted, and a track's drawbar pull predicted.

The data makers below write the CSV files a bevameter gives (shear test at several normal
pressures, plate sinkage test with several plate widths) from the textbook formulas written
out again in numpy, with Gaussian reading noise; the tests load them from here. Run as a
script it repeats the whole chain (simulate, ``fit_shear_test`` / ``fit_plate_test``,
``predict_drawbar_pull``) on many seeds and counts how often the 95 % intervals hold the
truth: the soil's six parameters and the light vehicle's drawbar pull at four slips; then it
times one shear and one plate fit against scipy's bounded ``curve_fit`` on the same data (scipy
is a benchmark-only dependency).

    python benchmarks/bevameter_to_track.py [--reps 200]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

#: The soil simulated: dry sand (Wong's table; K a typical value).
DRY_SAND = {"c": 1.04e3, "phi": math.radians(28.0), "K": 0.025, "k_c": 0.99e3, "k_phi": 1528.43e3, "n": 1.1}
#: A stiffer soil with a larger k_c (sandy loam, Wong's table).
SANDY_LOAM = {"c": 1.72e3, "phi": math.radians(29.0), "K": 0.01, "k_c": 5.27e3, "k_phi": 1515.04e3, "n": 0.7}
#: Light vehicle of the library (W = 300 N, l = 0.5 m, b = 0.1 m).
LIGHT = {"W": 300.0, "l": 0.5, "b": 0.1}


def shear_rows(
    soil: dict,
    seed: int,
    pressures=(10e3, 20e3, 40e3),
    j_max: float = 0.15,
    per_level: int = 25,
    noise_pa: float = 300.0,
) -> np.ndarray:
    """``[sigma, j, tau]`` rows of a shear test: tau = (c + sigma tan phi)(1 - exp(-j / K)) + noise."""
    rng = np.random.default_rng(seed)
    sig = np.repeat(np.asarray(pressures, dtype=float), per_level)
    j = np.tile(np.linspace(0.0, j_max, per_level), len(pressures))
    tau = (soil["c"] + sig * math.tan(soil["phi"])) * (1.0 - np.exp(-j / soil["K"]))
    return np.column_stack([sig, j, tau + rng.normal(0.0, noise_pa, sig.size)])


def plate_rows(
    soil: dict, seed: int, widths=(0.05, 0.1, 0.2), z_max: float = 0.06, per_level: int = 20, noise_pa: float = 1000.0
) -> np.ndarray:
    """``[b, p, z]`` rows of a plate test: p = (k_c / b + k_phi) z^n + noise."""
    rng = np.random.default_rng(seed + 10_000)
    b = np.repeat(np.asarray(widths, dtype=float), per_level)
    z = np.tile(np.linspace(0.0, z_max, per_level), len(widths))
    p = (soil["k_c"] / b + soil["k_phi"]) * z ** soil["n"]
    return np.column_stack([b, p + rng.normal(0.0, noise_pa, b.size), z])


def shear_csv(path: str, soil: dict, seed: int, **kw) -> None:
    """Write a shear-test CSV (columns of the data contract)."""
    np.savetxt(
        path,
        shear_rows(soil, seed, **kw),
        delimiter=",",
        comments="",
        header="normal_pressure_Pa,shear_displacement_m,shear_stress_Pa",
    )


def plate_csv(path: str, soil: dict, seed: int, **kw) -> None:
    """Write a plate-test CSV (columns of the data contract)."""
    np.savetxt(
        path, plate_rows(soil, seed, **kw), delimiter=",", comments="", header="plate_width_m,pressure_Pa,sinkage_m"
    )


def true_drawbar_pull(soil: dict, slip, W: float, l: float, b: float) -> np.ndarray:
    """Drawbar pull of both tracks: Eq. 2 thrust minus Bekker compaction resistance (plain numpy)."""
    i = np.asarray(slip, dtype=float)
    x = i * l / soil["K"]
    F = (2 * b * l * soil["c"] + W * math.tan(soil["phi"])) * (1.0 - (1.0 - np.exp(-x)) / x)
    k = soil["k_c"] / b + soil["k_phi"]
    z0 = (W / (2 * b * l) / k) ** (1.0 / soil["n"])
    R = 2 * b * k * z0 ** (soil["n"] + 1) / (soil["n"] + 1)
    return F - R


def main() -> None:
    from soiltrack.identify.soiltests import fit_plate_test, fit_shear_test, predict_drawbar_pull
    from soiltrack.soilmodel import VEHICLES, PlateTest, ShearTest

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=200)
    a = ap.parse_args()
    vehicle = VEHICLES["light"]  # W = 300 N, l = 0.5 m, b = 0.1 m as LIGHT
    slips = np.array([0.02, 0.1, 0.3, 0.6])
    for name, soil in (("dry_sand", DRY_SAND), ("sandy_loam", SANDY_LOAM)):
        keys = ("c", "phi", "K", "k_c", "k_phi", "n")
        hits = dict.fromkeys(keys, 0)
        dp_hits = np.zeros(slips.size)
        width = np.zeros(slips.size)
        ok = 0
        t0 = time.perf_counter()
        for seed in range(a.reps):
            s_rows, p_rows = shear_rows(soil, seed), plate_rows(soil, seed)
            fs = fit_shear_test(ShearTest(s_rows[:, 0], s_rows[:, 1], s_rows[:, 2]))
            fp = fit_plate_test(PlateTest(p_rows[:, 0], p_rows[:, 1], p_rows[:, 2]))
            ok += fs.success and fp.success
            truth = {
                "c": soil["c"] / 1e3,
                "phi": math.degrees(soil["phi"]),
                "K": soil["K"],
                "k_c": soil["k_c"] / 1e3,
                "k_phi": soil["k_phi"] / 1e3,
                "n": soil["n"],
            }
            est = dict(zip(keys, (*fs.parameters.values(), *fp.parameters.values())))
            for k in keys:
                lo, hi = est[k].edge_ci95
                hits[k] += bool(lo <= truth[k] <= hi)
            pr = predict_drawbar_pull(fs, fp, vehicle, slips)
            true_dp = true_drawbar_pull(soil, slips, LIGHT["W"], LIGHT["l"], LIGHT["b"])
            dp_hits += (pr.lower <= true_dp) & (true_dp <= pr.upper)
            width += (pr.upper - pr.lower) / a.reps
        dt = time.perf_counter() - t0
        print(
            f"{name}: {a.reps} simulated bevameter campaigns, both fits successful in {ok}; {dt:.1f} s "
            f"({1e3 * dt / a.reps:.1f} ms per campaign: two fits and one prediction)"
        )
        print("  95 % intervals holding the truth: " + ", ".join(f"{k} {hits[k] / a.reps:.0%}" for k in keys))
        true_dp = true_drawbar_pull(soil, slips, LIGHT["W"], LIGHT["l"], LIGHT["b"])
        for s, t, w, h in zip(slips, true_dp, width, dp_hits):
            print(
                f"  light track, slip {s:.2f}: true drawbar pull {t:7.1f} N, mean 95 % interval width {w:5.1f} N,"
                f" holds the truth in {h / a.reps:.0%}"
            )


def time_against_scipy(reps: int = 50) -> None:
    """Median time of one shear and one plate fit: soiltrack against scipy's bounded curve_fit (same data).

    scipy is what a user would script: ``curve_fit`` with the same bounds, its default start
    replaced by the same start as soiltrack's regression start would be unfair to neither, so
    scipy starts from the middle of the log-log line (n) and the largest readings (strengths).
    """
    from scipy.optimize import curve_fit

    from soiltrack.identify.soiltests import fit_plate_test, fit_shear_test
    from soiltrack.soilmodel import PlateTest, ShearTest

    soil = SANDY_LOAM
    ts, tp, ss, sp, agree = [], [], [], [], []
    for seed in range(reps):
        s_rows, p_rows = shear_rows(soil, seed), plate_rows(soil, seed)
        t0 = time.perf_counter()
        fs = fit_shear_test(ShearTest(s_rows[:, 0], s_rows[:, 1], s_rows[:, 2]))
        t1 = time.perf_counter()
        fp = fit_plate_test(PlateTest(p_rows[:, 0], p_rows[:, 1], p_rows[:, 2]))
        t2 = time.perf_counter()
        ts.append(t1 - t0)
        tp.append(t2 - t1)

        def tau(X, c, phi, K):
            return (c + X[0] * np.tan(phi)) * (1 - np.exp(-X[1] / K))

        def pres(X, kc, kphi, n):
            return (kc / X[0] + kphi) * X[1] ** n

        t0 = time.perf_counter()
        ps, cs = curve_fit(
            tau,
            (s_rows[:, 0], s_rows[:, 1]),
            s_rows[:, 2],
            p0=(1e3, 0.5, 0.01),
            bounds=((0.0, math.radians(1), 0.002), (200e3, math.radians(55), 0.25)),
        )
        t1 = time.perf_counter()
        pp, cp = curve_fit(
            pres,
            (p_rows[:, 0], p_rows[:, 2]),
            p_rows[:, 1],
            p0=(1e3, 1e6, 1.0),
            bounds=((0.0, 0.0, 0.05), (np.inf, np.inf, 2.5)),
        )
        t2 = time.perf_counter()
        ss.append(t1 - t0)
        sp.append(t2 - t1)
        ours = np.array([*fs.covariance.values, *fp.covariance.values])  # both identify all three
        theirs = np.concatenate([ps, pp])
        agree.append(float(np.max(np.abs(ours - theirs) / np.abs(theirs))))
    med = lambda x: 1e3 * float(np.median(x))  # noqa: E731
    print(
        f"speed ({reps} campaigns, sandy loam, median per fit): shear test soiltrack {med(ts):.1f} ms "
        f"(intervals included), scipy curve_fit {med(ss):.1f} ms; plate test soiltrack {med(tp):.1f} ms, "
        f"scipy {med(sp):.1f} ms; largest relative difference of the six estimates {max(agree):.1e}"
    )


if __name__ == "__main__":
    main()
    time_against_scipy()
