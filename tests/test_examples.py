"""Smoke test of examples/reproduce_paper.py: a --quick run writes the report and the figures."""

import os
import re
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "examples", "reproduce_paper.py")
# One --quick run of the paper's reproduction, a subprocess of about 8 s: in CI's full run, out of the quick loop.
pytestmark = pytest.mark.slow

FIGURES = (
    "fig2_backprediction.png",
    "fig3_sensitivity_heavy.png",
    "fig4_cohesion_heavy_vs_light.png",
    "fig5_models_vs_data.png",
    "fig6_model_errors.png",
    "fig7_traversability.png",
    "table2_noise.png",
    "robustness.png",
)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""), MPLBACKEND="Agg")
    proc = subprocess.run(
        [sys.executable, SCRIPT, "--quick", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out, open(out / "report.md", encoding="utf-8").read(), proc.stderr


def test_report_and_figures_exist(quick_run):
    out, report, _ = quick_run
    for name in FIGURES:
        path = out / name
        assert path.is_file(), name
        with open(path, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n", name
        assert path.stat().st_size > 10_000, name
        assert f"({name})" in report, f"report does not embed {name}"


def test_report_has_every_section(quick_run):
    _, report, _ = quick_run
    for heading in (
        "## Table 1",
        "## Table 2",
        "## Robustness",
        "## Figures 2-6",
        "## Fig. 7",
        "## Where this library agrees with the seed and where it does not",
    ):
        assert heading in report, heading
    assert "ASSUMES l = 2.8 m, b = 0.5 m" in report
    assert "--quick" in report and "50 noisy draws" in report


def test_key_numbers(quick_run):
    _, report, _ = quick_run
    # Wong's data with the seed's actual values at l = 2.8 m
    assert "207.89 kN (+0.28 %), 226.77 kN (+1.32 %), 253.00 kN (-2.62 %)" in report
    # the ridge: Newton is singular, c does not move, c and phi not identifiable
    assert re.search(r"returns status `Singular\w*` \(success = False", report)
    assert "c moved by 0 kPa from its start" in report
    assert "NOT IDENTIFIABLE" in report
    assert "correlation of the c and phi columns 1.000000000000" in report
    # identifiable combination from the three points: F_max and K of the full-model fit
    m = re.search(r"IPOPT, full model: status `\w+`, F_max = ([\d.]+) kN, K = ([\d.]+) m", report)
    assert m, "F_max/K statement missing"
    assert float(m.group(1)) == pytest.approx(289.76, abs=0.05)
    assert float(m.group(2)) == pytest.approx(0.02105, abs=1e-4)
    # no track length reproduces the three points better than about 2.2 %
    m = re.search(r"the best is l = ([\d.]+) m with max \|residual\| ([\d.]+) %", report)
    assert m and 2.85 < float(m.group(1)) < 2.95 and float(m.group(2)) == pytest.approx(2.22, abs=0.01)
    # Fig. 7: seed's reading and the consistent margin
    assert "dry sand 177.8 kN, clay 87.5 kN" in report
    assert "crosses both (GO / GO)" in report
    assert "on a 15 deg slope (101.0 kN required) it crosses dry sand (available 120.0 kN, GO) and not clay" in report
    assert "(available 84.0 kN, NO-GO)" in report
    # Table 2 ran with fit_many over the requested number of draws
    assert re.search(r"\| ipopt / cohesion-free \| \d+/50 ", report)


def test_progress_on_stderr(quick_run):
    _, _, err = quick_run
    assert "Table 2" in err and "robustness" in err
