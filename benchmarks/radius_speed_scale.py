"""A radius error against a speed-sensor scale: how far apart the held-out evidence puts them, in standard errors.

On the diagnosis grid's radius-error logs that were named ``unexplained`` with cause ``speed_scale`` before
the diagnosis judged collinear pairs by the standard error of their difference
(``python benchmarks/bench_diagnose.py --kinds drive``), this prints, per log, the verdict and its
confidence, the speed scale's weight from the evidence alone, and the difference of held-out log density
between the radius error and the speed scale (the evidence the pseudo-BMA+ weights are made of, summed
over the held-out samples) with its standard error from the hold-out blocks (the blocks the weights'
bootstrap draws: the separation the diagnosis reports for the pair, NaN when the pair is not confusable
by it), and the share of the nominal excess
error each one's refit removes. A weight near one at a difference of one or two standard errors is the
weight calling two hypotheses apart that the evidence does not separate.

Run:  python benchmarks/radius_speed_scale.py
"""

from __future__ import annotations

import importlib
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import bench_diagnose as grid  # noqa: E402

from soiltrack.identify import diagnose  # noqa: E402
from soiltrack.identify.diagnosis.evidence import log_density  # noqa: E402


#: (vehicle, terrain, eps, noise, seed): the grid's radius-error logs named ``unexplained`` on commit 1d64cb4.
CASES = [
    ("light", "lete_sand", 0.02, "double", 1),
    ("light", "lete_sand", 0.02, "double", 2),
    ("light", "lete_sand", 0.02, "double", 3),
    ("light", "lete_sand", 0.05, "double", 1),
    ("light", "dry_sand", 0.02, "double", 1),
    ("light", "dry_sand", 0.02, "double", 2),
    ("light", "dry_sand", 0.02, "double", 3),
    ("heavy", "lete_sand", 0.02, "default", 1),
    ("heavy", "lete_sand", 0.02, "double", 1),
    ("heavy", "dry_sand", 0.02, "double", 1),
]


def _share(x) -> str:
    """A share removed, or n/a."""
    return f"{x:7.2f}" if x is not None else f"{'n/a':>7s}"


def main() -> None:
    steps = importlib.import_module("soiltrack.identify.diagnosis.diagnose")
    decide = steps.decide
    seen: dict = {}

    def keep(hyps, *args, **kw):
        seen["hyps"] = {h.name: h for h in hyps}
        return decide(hyps, *args, **kw)

    steps.decide = keep
    print(
        f"{'log':48s} {'verdict':12s} {'conf':>5s} {'w_ss':>5s} {'diff':>8s} {'SE':>7s} {'diff/SE':>8s} "
        f"{'expl_r':>7s} {'expl_s':>7s}"
    )
    for vname, tname, eps, noise, seed in CASES:
        vehicle = grid.VEHICLES[vname]
        data = grid.make(
            "drive", vehicle, grid.TERRAINS[tname], {"radius_error": eps}, seed, grid.NOISE["drive"][noise]
        )
        d = diagnose(data, vehicle)
        hs = seen["hyps"]
        if "radius_error" not in hs or "speed_scale" not in hs:
            print(f"{vname} {tname} eps {eps} {noise} s{seed}: radius error or speed scale not admissible")
            continue
        # the separation the diagnosis computed (its own hold-out blocks), when it made the pair confusable
        pair = next((c for c in d.confusable if set(c.effects) == {"radius_error", "speed_scale"}), None)
        z = pair.separation if pair is not None else float("nan")
        diff = float(np.sum(log_density(hs["radius_error"]) - log_density(hs["speed_scale"])))
        raw = {e.effect: e.evidence_weight for e in d.ranking}
        ex = {e.effect: e.explained for e in d.ranking}
        label = f"{vname} {tname} eps {eps} noise {noise} seed {seed}"
        print(
            f"{label:48s} {d.verdict:12s} {d.confidence:5.2f} {raw['speed_scale']:5.2f} {diff:8.1f} "
            f"{abs(diff) / z if z > 0 else float('nan'):7.1f} {math.copysign(z, diff):8.2f} "
            f"{_share(ex['radius_error'])} {_share(ex['speed_scale'])}",
            flush=True,
        )
    steps.decide = decide


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()
    main()
