"""Drawbar-pull data through the command line: fit, figure and JSON (no traceback)."""

import json

from soiltrack.cli import main
from soiltrack.soilmodel import TERRAINS, VEHICLES, read_csv, write_csv
from soiltrack.soilmodel.simulation import simulate_slip_sweep


def test_fit_drawbar_csv_with_plot(tmp_path, capsys):
    data = simulate_slip_sweep(VEHICLES["light"], TERRAINS["dry_sand"], measure="drawbar_pull", seed=1)
    csv, png = tmp_path / "dp.csv", tmp_path / "dp.png"
    write_csv(data, str(csv))
    assert read_csv(str(csv)).measured == "drawbar_pull"
    assert main(["fit", str(csv), "--vehicle", "light", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["success"] is True
    assert png.stat().st_size > 10_000
