"""What a drive log's held-out channels say about the torque hold, on a log of each hold.

Two logs:

* ``sampled``: the independent generator of ``benchmarks/independent_check.py`` (plain numpy, heavy
  vehicle, 60 s at 50 Hz, the torque a continuous signal read at each sample) with a 10 % mass error;
* ``held``: the library's simulator (it holds each torque over its sample), the heavy vehicle on LETE
  sand with a 0.03 rad grade, 60 s (the log of ``bench_diagnose_speed.py``).

Each is diagnosed with the hold given as ``"zoh"`` and as ``"sample"``, and not given. Printed per
hold: the nominal model's held-out RMS per channel (fitted on the even blocks, predicting the odd
ones), the noise floor per channel, the verdict and its confidence; and the hold chosen when not
given. The thrust channel is built from the torque and the sprocket acceleration with each hold's own
discretisation, so the two holds are compared on different derived data: if the pattern of the RMS
is the same on both logs, the held-out comparison cannot tell which hold made the data.

Run:  python benchmarks/hold_channels.py [--seed 1]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import independent_check as ic  # noqa: E402

from soiltrack.identify import diagnose  # noqa: E402
from soiltrack.soilmodel import TERRAINS, VEHICLES, Vehicle, read_csv, simulate  # noqa: E402


def _logs(seed: int):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "sampled.csv")
        ic.log_csv(path, seed, mass=0.1, rate=50.0)
        sampled = read_csv(path)
    heavy = VEHICLES["heavy"]
    held = simulate(heavy, TERRAINS["lete_sand"], kind="drive", effects={"grade": 0.03}, seed=seed, duration_s=60)
    return [
        ("sampled (independent, mass_error 0.1)", sampled, Vehicle.from_json(ic.VEHICLE)),
        ("held (library simulator, grade 0.03)", held, heavy),
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    for name, log, vehicle in _logs(a.seed):
        print(f"{name}: {log.n_samples} samples")
        for hold in ("zoh", "sample"):
            d = diagnose(log, vehicle, torque_hold=hold)
            rms = ", ".join(f"{ch} {v:.4g}" for ch, v in d.holdout_rmse_before.items())
            floor = ", ".join(f"{ch} {v:.4g}" for ch, v in d.noise.items())
            print(f"  given {hold:6s}: held-out RMS of the nominal model: {rms}")
            print(f"                 noise floor: {floor}")
            print(f"                 verdict {d.verdict}, confidence {d.confidence:.2f}")
        d = diagnose(log, vehicle)
        h = d.torque_hold
        print(
            f"  not given: hold {h.hold} (the sampled one's held-out error {-h.shrink:+.1%}, p = {h.p_value:.2g}); "
            f"verdict {d.verdict}, confidence {d.confidence:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
