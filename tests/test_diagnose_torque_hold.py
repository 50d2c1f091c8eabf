"""A drive log whose torque is a sampled continuous signal (a transducer), not a held command."""
import json

import pytest

from conftest import bench_module
from soiltrack.identify import diagnose
from soiltrack.soilmodel import TERRAINS, VEHICLES, Vehicle, simulate

SHAPES = bench_module("soil_range_and_torque_hold")
MID = Vehicle.from_json(json.dumps(SHAPES.MID))


@pytest.mark.parametrize("seed", [0, 3])
def test_a_sampled_torque_is_recognised_and_not_read_as_a_drivetrain_loss(seed):
    # independent numpy, 10 Hz stop and go, the torque read as a transducer does (r F + I dw/dt at each sample)
    log = SHAPES.stop_and_go_log(seed)
    held = diagnose(log, MID, torque_hold="zoh")
    # taken as held, the torque's change over one sample reads as a drivetrain loss (3 of seeds 0-7 at >= 0.99; the
    # diagnosis' default was "zoh" before "auto")
    assert held.verdict == "drivetrain_friction" and held.confidence > 0.9, (held.verdict, held.confidence)
    d = diagnose(log, MID)
    assert d.verdict == "none", (d.verdict, d.confidence, d.notes)
    assert "torque_hold='sample'" in d.notes[0] and "likelihood ratio" in d.notes[0]


def test_a_held_torque_stays_held():
    # the library's simulator holds each torque command over its sample: auto keeps zoh
    v = VEHICLES["heavy"]
    d = diagnose(simulate(v, TERRAINS["lete_sand"], kind="drive", seed=3), v)
    assert any("torque_hold='zoh'" in n and "does not fit the log significantly better" in n for n in d.notes)
    assert d.verdict == "none", (d.verdict, d.notes)
