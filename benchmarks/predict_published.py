"""Forward predictions against published measured pulls: `soiltrack predict` beside an independent numpy copy.

For each published test with its published soil values, the library's forward prediction
(``soiltrack predict ... --json``, the CLI a designer runs) and the same equation written out again
here in numpy (Janosi-Hanamoto thrust of a track, Eq. 2 of docs/physics.md) are compared with the
measured numbers; the table prints each point's relative error and the median absolute error of
each implementation. Data (benchmarks/data/, each file citing its source and table/page):

- ``wong2001_p176_heavy_track.csv``: Wong (2001), Theory of Ground Vehicles, p. 176 - tractive force of
  a heavy tracked vehicle (W = 329 kN) at three slips, soil c = 0.55 kPa, phi = 40.1 deg, K = 0.018 m
  (as quoted by the seed paper); track geometry the ``heavy`` preset's (assumed: l = 2.8 m, b = 0.5 m).

No single-wheel data set with published soil values and tabulated measured pulls was available to
this benchmark; a wheel case is added here when one is (see docs/measured-data.md).

    python benchmarks/predict_published.py
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data"

#: Published cases: file, gear, soil (c kPa, phi deg, K m), load N, the geometry written out here (m).
CASES = (
    {
        "name": "Wong 2001 p. 176, heavy tracked vehicle",
        "file": "wong2001_p176_heavy_track.csv",
        "vehicle": "heavy",
        "soil": (0.55, 40.1, 0.018),
        "W": 329000.0,
        "l": 2.8,
        "b": 0.5,
    },
)


def numpy_thrust(slip: np.ndarray, c_kpa: float, phi_deg: float, K: float, W: float, l: float, b: float) -> np.ndarray:
    """Janosi-Hanamoto thrust of both tracks, written out independently: (A c + W tan phi)(1 - K/(il)(1 - e^-il/K))."""
    A = 2.0 * b * l
    x = slip * l / K
    return (A * c_kpa * 1e3 + W * math.tan(math.radians(phi_deg))) * (1.0 - (1.0 - np.exp(-x)) / x)


def library_prediction(case: dict, slips: np.ndarray) -> np.ndarray:
    """The thrust from ``soiltrack predict --vehicle V --soil C,PHI,K --slip S1,S2,... --json``."""
    from soiltrack.cli import main

    soil = ",".join(f"{v:g}" for v in case["soil"])
    args = ["predict", "--vehicle", case["vehicle"], "--soil", soil, "--slip", ",".join(f"{s:g}" for s in slips)]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        code = main(args + ["--json"])
    if code != 0:
        raise SystemExit(f"soiltrack {' '.join(args)} exited {code}")
    return np.array(json.loads(buf.getvalue())["thrust_N"], dtype=float)


def read_case(case: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(slip, measured force N)`` of a case's file (comment lines ``#``, then a header, then rows)."""
    lines = [ln for ln in (DATA / case["file"]).read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    body = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    return body[:, 0], body[:, 1]


def run() -> list[dict]:
    """Every case: measured, library and numpy values, their relative errors (%)."""
    out = []
    for case in CASES:
        slips, measured = read_case(case)
        lib = library_prediction(case, slips)
        ref = numpy_thrust(slips, *case["soil"], case["W"], case["l"], case["b"])
        out.append(
            {
                "case": case["name"],
                "slip": slips,
                "measured": measured,
                "library": lib,
                "numpy": ref,
                "err_lib_pct": 100 * (lib / measured - 1),
                "err_np_pct": 100 * (ref / measured - 1),
            }
        )
    return out


def main() -> None:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    results = run()
    print(f"{'case':<42}{'slip':>8}{'measured kN':>13}{'library kN':>12}{'numpy kN':>10}{'lib %':>8}{'numpy %':>9}")
    all_lib, all_np = [], []
    for r in results:
        for k in range(r["slip"].size):
            print(
                f"{r['case']:<42}{r['slip'][k]:>8.4f}{r['measured'][k] / 1e3:>13.2f}{r['library'][k] / 1e3:>12.2f}"
                f"{r['numpy'][k] / 1e3:>10.2f}{r['err_lib_pct'][k]:>+8.2f}{r['err_np_pct'][k]:>+9.2f}"
            )
        all_lib += list(np.abs(r["err_lib_pct"]))
        all_np += list(np.abs(r["err_np_pct"]))
    print(
        f"median |error| over {len(all_lib)} points: library {np.median(all_lib):.2f} %, "
        f"independent numpy {np.median(all_np):.2f} %"
    )


if __name__ == "__main__":
    main()
