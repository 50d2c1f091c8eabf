"""Coverage of the sinkage channel's 95 % intervals and the slip-sinkage evidence's error rates.

Track sweeps with ``sinkage_m`` made in plain numpy from the textbook formulas (Bekker's static
sinkage ``(W / (2 b l k)) ^ (1 / n)`` times Lyasko's factor ``(1 + i) / (1 - 0.5 i)`` to the
power s, log-normal reading errors; sandy loam n = 0.7, k = k_c / b + k_phi at b = 0.1 m; 7 slips
0.03-0.7 at each load), fitted by :func:`soiltrack.identify.fit_sinkage_channel`:

- how often the 95 % intervals of n, k and the slip exponent s cover the truth;
- how often :func:`soiltrack.identify.slip_sinkage_evidence` finds slip sinkage (p < 0.05 for
  s = 0) when it is there (s = 1) and when it is not (s = 0), and how often it refutes Lyasko's
  law when the law holds.

    python benchmarks/sinkage_channel_coverage.py [--runs 1000]
"""

from __future__ import annotations

import argparse

import numpy as np

from soiltrack.identify import fit_sinkage_channel, slip_sinkage_evidence
from soiltrack.soilmodel import SlipData, Vehicle

L, B = 0.5, 0.1
TRACK = Vehicle(
    mass=30.0, track_length=L, track_width=B, sprocket_radius=0.08, sprocket_inertia=0.05, rolling_resistance=0.05
)
N_TRUE, K_TRUE = 0.7, 5.27e3 / B + 1515.04e3
SLIPS = np.array([0.03, 0.08, 0.15, 0.25, 0.4, 0.55, 0.7])


def sweep(seed: int, loads: tuple[float, ...], s_exp: float, rel: float) -> SlipData:
    rng = np.random.default_rng(seed)
    i = np.tile(SLIPS, len(loads))
    W = np.repeat(np.asarray(loads, dtype=float), SLIPS.size)
    z = (W / (2 * B * L * K_TRUE)) ** (1 / N_TRUE) * ((1 + i) / (1 - 0.5 * i)) ** s_exp
    z = z * np.exp(rng.normal(0.0, rel, i.size))
    return SlipData(slip=i, drawbar_pull=np.full(i.shape, 100.0), normal_load=W, sinkage=z)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    runs = ap.parse_args().runs
    truth = {"bekker_n": N_TRUE, "bekker_k_eq": K_TRUE, "slip_sinkage_exponent": 1.0}
    for loads, rel in (((220.0, 300.0, 400.0), 0.05), ((250.0, 350.0), 0.03)):
        hits = dict.fromkeys(truth, 0)
        found_present = found_absent = lyasko_refuted = 0
        for seed in range(runs):
            data = sweep(seed, loads, 1.0, rel)
            ch = fit_sinkage_channel(data, TRACK)
            assert ch is not None and ch.converged
            for key in hits:
                lo, hi = ch.parameters[key].ci95
                hits[key] += int(lo is not None and hi is not None and lo <= truth[key] <= hi)
            ev = slip_sinkage_evidence(data, TRACK)
            found_present += ev.found()
            lyasko_refuted += int(ev.p_lyasko is not None and ev.p_lyasko < 0.05)
            found_absent += slip_sinkage_evidence(sweep(seed, loads, 0.0, rel), TRACK).found()
        cover = ", ".join(f"{k} {100 * v / runs:.1f} %" for k, v in hits.items())
        print(f"loads {loads} N, {100 * rel:.0f} % reading error, {runs} sweeps of {SLIPS.size * len(loads)} rows:")
        print(f"  95 % intervals cover the truth: {cover}")
        print(
            f"  slip sinkage found: {100 * found_present / runs:.1f} % when present (s = 1), "
            f"{100 * found_absent / runs:.1f} % when absent (s = 0); Lyasko's law refuted when it holds: "
            f"{100 * lyasko_refuted / runs:.1f} %"
        )


if __name__ == "__main__":
    main()
