"""benchmarks/predict_published.py: `soiltrack predict` on published measured pulls, beside an independent numpy
copy of the same equation (the two must agree; their error against the measurements is the benchmark's report)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from soiltrack.cli import main

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "predict_published.py"


def _bench():
    spec = importlib.util.spec_from_file_location("predict_published", BENCH)
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    return mod


def test_library_prediction_equals_the_independent_numpy_copy_on_published_cases():
    res = _bench().run()
    assert res, "no published case"
    for r in res:
        assert r["measured"].size >= 3
        np.testing.assert_allclose(r["library"], r["numpy"], rtol=1e-9)
        # a forward prediction, not a fit: the errors are what they are, but finite and not all zero
        assert np.all(np.isfinite(r["err_lib_pct"])) and np.any(np.abs(r["err_lib_pct"]) > 1e-6)


def test_predict_takes_a_list_of_slips_and_refuses_a_bad_one(capsys):
    assert main(["predict", "--vehicle", "light", "--terrain", "dry_sand", "--slip", "0.05,0.1,0.3", "--json"]) == 0
    import json

    js = json.loads(capsys.readouterr().out)
    assert js["slip"] == [0.05, 0.1, 0.3]
    for bad, word in (("0.3,0.1", "increase"), ("0.1,x", "list"), ("0.1,1.2", "[-1, 1)")):
        assert main(["predict", "--vehicle", "light", "--terrain", "dry_sand", "--slip", bad]) == 2
        err = capsys.readouterr().err
        assert word in err and "Traceback" not in err, err


@pytest.mark.parametrize("text", ["0.1", "0.1,0.2"])
def test_slip_list_values(text):
    from soiltrack.cmd_predict import slip_arg

    assert slip_arg(text) == [float(v) for v in text.split(",")]
