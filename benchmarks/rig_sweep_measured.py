"""Measured single-wheel trials (CMU 3d-terramechanics, smooth wheel) through the rig-sweep path.

The wheel is approximated as two tracks, as a new user would: contact length l = r theta_1 from
the mean sinkage (cos theta_1 = 1 - z / r), b so that 2 b l is the wheel's contact area, the
mean measured load as the weight, rolling resistance 0. The script writes the rig CSV (all 189
trials with their slip angles, skid rows, std and sinkage columns) and the vehicle JSON into a
folder, then runs what the command line runs:

- reading the whole file: refused (count of skid and slip-angle rows); with ``driving_only`` and
  ``slip_angle=0``: the 12 driving straight trials, the rest counted;
- the fit with the assumed resistance and with ``resistance="fit"``: report length, mu_r and its
  interval, the pure-error lack-of-fit test;
- leave-one-slip-level-out prediction error of the fit (``FitResult.predict`` on the held-out
  level) against a constant (the mean pull of the other levels).

    python benchmarks/rig_sweep_measured.py [--trials PATH] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import tempfile

import numpy as np

TRIALS = "/work/shared/data/cmu-3dterra/smooth_wheel_trials.csv"
RADIUS, WIDTH = 0.058, 0.050


def write_rig_files(trials: str, out: str) -> tuple[str, str]:
    """The rig CSV (contract columns) and the two-track vehicle JSON; returns their paths."""
    rows = list(csv.DictReader(open(trials)))
    path = os.path.join(out, "smooth_wheel_rig.csv")
    with open(path, "w") as fh:
        fh.write("slip,drawbar_pull_N,drawbar_pull_std_N,normal_load_N,sinkage_m,slip_angle_deg\n")
        for r in rows:
            fh.write(
                f"{r['slip']},{r['drawbar_pull_N']},{r['drawbar_pull_std_N']},{r['normal_load_N']},"
                f"{float(r['sinkage_mm']) / 1e3!r},{r['beta_deg_nominal']}\n"
            )
    drive = [r for r in rows if float(r["beta_deg_nominal"]) == 0 and float(r["slip"]) >= 0]
    z = np.mean([float(r["sinkage_mm"]) / 1e3 for r in drive])
    W = np.mean([float(r["normal_load_N"]) for r in drive])
    l = RADIUS * math.acos(1 - z / RADIUS)
    vj = os.path.join(out, "wheel_as_tracks.json")
    json.dump(
        {
            "mass_kg": W / 9.81,
            "track_length_m": l,
            "track_width_m": WIDTH / 2,
            "sprocket_radius_m": RADIUS,
            "sprocket_inertia_kg_m2": 0.001,
            "rolling_resistance": 0.0,
        },
        open(vj, "w"),
    )
    return path, vj


def main() -> None:
    from soiltrack.identify import fit
    from soiltrack.identify.sweep.rig import slip_levels
    from soiltrack.soilmodel import DataError, Vehicle, read_csv

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", default=TRIALS)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp()
    path, vj = write_rig_files(a.trials, out)
    vehicle = Vehicle.from_json(vj)
    try:
        read_csv(path)
    except DataError as e:
        print(f"whole file refused: {len(e.rows)} rows named (skid and slip-angle rows together)")
    data = read_csv(path, driving_only=True, slip_angle=0.0)
    print(
        f"kept {data.n_samples} rows; dropped " + ", ".join(f"{len(r)} {why} ({opt})" for why, opt, r in data.dropped)
    )
    for mode in ("assumed", "fit"):
        r = fit(data, vehicle, resistance=mode)
        x = r.extra
        print(f"\nresistance {mode}: {r.status}; report {len(r.report().splitlines())} lines")
        print("  " + x["resistance"]["statement"])
        if "lack_of_fit" in x:
            print("  " + x["lack_of_fit"]["statement"])
        if mode == "assumed" and (x.get("sinkage_m") or {}).get("laws"):
            print("  sinkage: " + x["sinkage_m"]["laws"]["statement"])
        print(
            "  "
            + "; ".join(
                f"{pe.edge_value:.4g} {pe.edge_unit} [{pe.edge_ci95[0]:.4g}, {pe.edge_ci95[1]:.4g}]"
                for pe in r.parameters.values()
                if pe.value is not None
            )
        )
    level = slip_levels(data.slip)
    err_fit, err_const = [], []
    for k in range(level.max() + 1):
        train, held = data.subset(level != k), data.subset(level == k)
        r = fit(train, vehicle, resistance="fit")
        if not r.success:
            print(f"held-out level {k}: the fit did not succeed ({r.status})")
            continue
        err_fit += list(held.values - r.predict(held))
        err_const += list(held.values - train.values.mean())
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    print(
        f"\nleave-one-slip-level-out ({level.max() + 1} levels): rms error of the fit {rms(err_fit):.3f} N, "
        f"of a constant {rms(err_const):.3f} N"
    )


if __name__ == "__main__":
    main()
