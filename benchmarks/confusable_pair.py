"""Which member of a confusable pair the verdict names, against the truth and against the log's seed.

Two library effects whose sensitivities are collinear on a log and whose held-out evidence lies
within two standard errors share their weight (0.50 each); the verdict names the one with the larger
weight from the evidence alone (the tie-break), and lists the pair under ``confusable`` with the
experiment that separates them. This runs the diagnosis grid's drive logs of two such effects
(``python benchmarks/bench_diagnose.py --kinds drive``: two vehicles, two terrains, two noise levels, two
magnitudes, seeds 1-3) and counts the verdicts by true effect and by seed. When the tie-break follows
the seed (the log's driving and noise) rather than the true effect, the evidence carries no information
about which of the two it is: the count of right names in the pair is a coin flip, not a measure of the
diagnosis.

Run:  python benchmarks/confusable_pair.py [--effects grade,drivetrain_friction] [--seeds 1,2,3]
"""

from __future__ import annotations

import argparse
import collections
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import bench_diagnose as grid  # noqa: E402

from soiltrack.identify import diagnose  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--effects", default="grade,drivetrain_friction", help="the pair, comma-separated")
    ap.add_argument("--seeds", default="1,2,3")
    a = ap.parse_args(argv)
    pair = tuple(a.effects.split(","))
    seeds = tuple(int(s) for s in a.seeds.split(","))
    by_truth: collections.Counter = collections.Counter()
    by_seed: collections.Counter = collections.Counter()
    for eff in pair:
        for vname in grid.GRID_VEHICLES:
            v = grid.VEHICLES[vname]
            for tname in grid.GRID_TERRAINS:
                for nname in grid.NOISE["drive"]:
                    for mag in grid.magnitudes(eff, v):
                        for seed in seeds:
                            data = grid.make(
                                "drive", v, grid.TERRAINS[tname], {eff: mag}, seed, grid.NOISE["drive"][nname]
                            )
                            d = diagnose(data, v)
                            raw = {
                                e.effect: e.weight if e.evidence_weight is None else e.evidence_weight
                                for e in d.ranking
                            }
                            shared = any(set(pair) <= set(c.effects) for c in d.confusable)
                            print(
                                f"{eff:20s} {vname:5s} {tname:9s} {nname:7s} {mag:8.4g} s{seed} -> {d.verdict:20s} "
                                f"{d.confidence:.2f}  evidence alone: "
                                + ", ".join(f"{p} {raw.get(p, float('nan')):.2f}" for p in pair)
                                + ("  (pair confusable)" if shared else ""),
                                file=sys.stderr,
                                flush=True,
                            )
                            by_truth[(eff, d.verdict)] += 1
                            by_seed[(seed, d.verdict)] += 1
    print("verdicts by true effect:")
    for (truth, verdict), n in sorted(by_truth.items()):
        print(f"  {truth:20s} -> {verdict:20s} {n}")
    print("verdicts by seed (both true effects together):")
    for (seed, verdict), n in sorted(by_seed.items()):
        print(f"  seed {seed} -> {verdict:20s} {n}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
