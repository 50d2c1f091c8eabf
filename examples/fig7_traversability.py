"""The seed's Fig. 7, as the seed draws it and as it should be read (docs/paper.md).

The seed compares a UGV "able to produce 120 kN" with a "tractive force required" of about
180 kN on dry sand and 90 kN on clayey soil, and concludes that the vehicle crosses the clay
but not the sand. Those two numbers are the soils' own thrust limits ``A c + W tan(phi)`` for
the heavy vehicle (W = 329 kN, A = 2.8 m^2): what the soil CAN give, not what the vehicle
NEEDS. The vehicle is stopped when the thrust it can get - the smaller of its drivetrain's
120 kN and what the soil gives at an acceptable slip - falls below the resistance it must
overcome. Computed through :func:`soiltrack.planning.margin`:

- flat ground: both soils traversable;
- 15 deg slope (about 101 kN of rolling and grade resistance, plus compaction): dry sand
  traversable, clayey soil NOT - the opposite of the seed's reading.

Usage::

    python examples/fig7_traversability.py [--out PNG]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))  # run from a source checkout without installing

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from soiltrack.planning import margin  # noqa: E402
from soiltrack.soilmodel import TERRAINS, VEHICLES, max_thrust  # noqa: E402

#: The heavy reference vehicle with the seed's 120 kN of drivetrain thrust (36 kN m at r = 0.3 m).
VEHICLE = dataclasses.replace(
    VEHICLES["heavy"],
    max_sprocket_torque=36_000.0,
    max_power=None,
    name="heavy (W = 329 kN, geometry assumed), 120 kN drivetrain",
)
SOILS = ("dry_sand", "clayey_soil")
GRADES = (0.0, 15.0)


def compute():
    """Seed's numbers (soil limits) and the margins, per soil and grade."""
    seed = {k: max_thrust(TERRAINS[k], VEHICLE) for k in SOILS}
    margins = {(k, g): margin(TERRAINS[k], VEHICLE, grade_deg=g) for k in SOILS for g in GRADES}
    return seed, margins


def plot(seed, margins, path: str) -> None:
    """Left: the seed's drawing. Right: available against required thrust, flat and on 15 deg."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [1, 2]})
    names = {"dry_sand": "dry sand", "clayey_soil": "clayey soil"}
    x = np.arange(len(SOILS))
    a1.bar(x, [seed[k] / 1e3 for k in SOILS], color=["#d9b36c", "#8c6d46"], width=0.6)
    a1.axhline(120, color="C3", lw=2, label="UGV able to produce 120 kN")
    for i, k in enumerate(SOILS):
        a1.text(i, seed[k] / 1e3 + 3, f"{seed[k] / 1e3:.0f} kN", ha="center")
    a1.set_xticks(x, [names[k] for k in SOILS])
    a1.text(0.5, 200, "seed's reading: sand NO GO, clay GO", ha="center", fontsize=8)
    a1.set_ylabel("thrust (kN)")
    a1.set_title(
        "As the seed draws it: 'tractive force required'\n= the soil's limit A c + W tan(phi) (what the soil CAN give)",
        fontsize=9,
    )
    a1.legend(loc="upper right", fontsize=8)
    a1.set_ylim(0, 220)

    items = [
        ("rolling_N", "rolling mu_r W cos(theta)", "#999999"),
        ("compaction_N", "Bekker compaction", "#6a8caf"),
        ("grade_N", "grade W sin(theta)", "#c96f53"),
    ]
    labels, pos = [], []
    for j, g in enumerate(GRADES):
        for i, k in enumerate(SOILS):
            m = margins[(k, g)]
            p = j * 3 + i
            pos.append(p)
            labels.append(f"{names[k]}\n{g:g} deg")
            bottom = 0.0
            for key, lab, col in items:
                a2.bar(p - 0.18, m.required[key] / 1e3, 0.34, bottom=bottom, color=col, label=lab if p == 0 else None)
                bottom += m.required[key] / 1e3
            a2.bar(
                p + 0.18,
                m.soil_limit_N / 1e3,
                0.34,
                color="#e8d9b0",
                edgecolor="k",
                lw=0.5,
                label="soil at 20 % slip" if p == 0 else None,
            )
            a2.plot([p + 0.01, p + 0.35], [120, 120], color="C3", lw=2, label="drivetrain 120 kN" if p == 0 else None)
            verdict = "GO" if m.traversable else "NO GO"
            a2.text(
                p,
                max(m.soil_limit_N, m.required_N, 120e3) / 1e3 + 6,
                f"{verdict}\nmargin {m.margin_N / 1e3:+.0f} kN",
                ha="center",
                fontsize=8,
                color="green" if m.traversable else "red",
            )
    a2.set_xticks(pos, labels, fontsize=8)
    a2.set_ylabel("thrust (kN)")
    a2.set_ylim(0, 230)
    a2.set_title(
        "As it should be read: required (left bar) against available = min(soil at 20 % slip, drivetrain)", fontsize=9
    )
    a2.legend(fontsize=7, loc="upper left", ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(HERE, "out", "fig7_traversability.png"), help="PNG to write")
    a = ap.parse_args(argv)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    seed, margins = compute()
    print("Seed's 'tractive force required' = soil limit A c + W tan(phi):")
    for k in SOILS:
        print(f"  {k:12s} {seed[k] / 1e3:6.1f} kN")
    print("Physically consistent margins (120 kN drivetrain, 20 % slip allowed):")
    for (k, g), m in margins.items():
        print(
            f"  {k:12s} {g:4.0f} deg: available {m.available_N / 1e3:6.1f} kN ({m.limited_by}), required "
            f"{m.required_N / 1e3:6.1f} kN, margin {m.margin_N / 1e3:+6.1f} kN -> "
            f"{'traversable' if m.traversable else 'NOT traversable'}"
        )
    plot(seed, margins, a.out)
    print(f"figure: {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
