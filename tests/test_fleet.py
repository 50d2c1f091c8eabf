"""Fleets of drive logs (issue 40, item 5): ``fit_many`` over log files on a dask LocalCluster and a process pool,
rows written to a results file as the fits finish, a poisoned log failing alone with its reason."""

import csv
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from soiltrack.identify import fit, fit_many
from soiltrack.identify.fleet import FLEET_COLUMNS, FleetWriter
from soiltrack.identify.segments import SegmentMap, fit_segments
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError
from soiltrack.soilmodel.data import read_csv, write_csv
from soiltrack.soilmodel.simulation import simulate_drive_log

LIGHT = VEHICLES["light"]
FORK = multiprocessing.get_context("fork") if "fork" in multiprocessing.get_all_start_methods() else None


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Three 20 s logs of dry sand and one poisoned log (a non-numeric cell in row 7)."""
    d = tmp_path_factory.mktemp("fleet")
    paths = []
    for s in (1, 2, 3):
        p = d / f"log{s}.csv"
        write_csv(simulate_drive_log(LIGHT, TERRAINS["dry_sand"], seed=s, duration_s=20.0), p)
        paths.append(str(p))
    lines = open(paths[0]).read().splitlines()
    cells = lines[7].split(",")
    cells[1] = "oops"
    lines[7] = ",".join(cells)
    bad = d / "poisoned.csv"
    bad.write_text("\n".join(lines) + "\n")
    paths.insert(2, str(bad))
    return paths


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _check_rows(rows, paths, serial):
    assert len(rows) == len(paths)
    by_index = {int(r["index"]): r for r in rows}
    assert sorted(by_index) == list(range(len(paths)))
    for k, p in enumerate(paths):
        r = by_index[k]
        assert r["source"] == p
        if "poisoned" in p:
            assert r["outcome"] == "failed" and r["error"] == "DataError"
            assert "sprocket_torque_Nm" in r["reason"] and "row 7" in r["reason"] and p in r["reason"]
            assert r["max_thrust_N"] == ""
            continue
        res = serial[p]
        F = res.to_dict()["combinations"]
        F = next(c for c in F if c["name"].startswith("F_max"))
        assert float(r["max_thrust_N"]) == pytest.approx(F["value"], rel=1e-9)
        assert float(r["max_thrust_ci95_lo"]) < float(r["max_thrust_N"]) < float(r["max_thrust_ci95_hi"])
        assert r["outcome"] == res.to_dict()["outcome"] and r["reason"] == ""
        assert int(r["rows"]) == 1001 and float(r["end_s"]) == pytest.approx(20.0)
        assert float(r["distance_m"]) > 0


@pytest.fixture(scope="module")
def serial(fleet):
    return {p: fit(read_csv(p), LIGHT) for p in fleet if "poisoned" not in p}


def test_fleet_serial_writes_every_row_and_the_poisoned_logs_reason(fleet, serial, tmp_path):
    out = tmp_path / "fleet.csv"
    res = fit_many(fleet, LIGHT, out=out, progress=False)
    assert [r.success for r in res].count(False) >= 1
    bad = res[2]
    assert bad.status == "not fitted" and "batch item 2" in bad.message and "row 7" in bad.message
    for k in (0, 1, 3):
        np.testing.assert_allclose(res[k].theta, serial[fleet[k]].theta, rtol=1e-12)
    rows = _rows(out)
    assert tuple(rows[0].keys()) == FLEET_COLUMNS
    _check_rows(rows, fleet, serial)


def test_fleet_on_a_dask_local_cluster(fleet, serial, tmp_path):
    distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed (soiltrack[dask])")
    out = tmp_path / "dask.csv"
    with (
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cl,
        distributed.Client(cl) as client,
    ):
        res = fit_many(fleet, LIGHT, executor=client.get_executor(), chunk_size=1, out=out, progress=False)
    assert res[2].status == "not fitted"
    for k in (0, 1, 3):
        np.testing.assert_allclose(res[k].theta, serial[fleet[k]].theta, rtol=1e-12)
    _check_rows(_rows(out), fleet, serial)


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
@pytest.mark.skipif(FORK is None, reason="needs the fork start method")
def test_fleet_on_a_process_pool(fleet, serial, tmp_path):
    out = tmp_path / "pool.csv"
    with ProcessPoolExecutor(2, mp_context=FORK) as ex:
        res = fit_many(fleet, LIGHT, executor=ex, chunk_size=1, out=out, progress=False)
    for k in (0, 1, 3):
        np.testing.assert_allclose(res[k].theta, serial[fleet[k]].theta, rtol=1e-12)
    _check_rows(_rows(out), fleet, serial)


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
@pytest.mark.skipif(FORK is None, reason="needs the fork start method")
def test_fleet_of_segment_maps(fleet, tmp_path):
    out = tmp_path / "seg.csv"
    with ProcessPoolExecutor(2, mp_context=FORK) as ex:
        res = fit_many(fleet, LIGHT, executor=ex, chunk_size=1, out=out, segments="10s", progress=False)
    assert isinstance(res[0], SegmentMap) and res[2].status == "not fitted"
    want = fit_segments(read_csv(fleet[0]), LIGHT, "10s")
    assert [s.to_dict() for s in res[0].segments] == [s.to_dict() for s in want.segments]
    rows = _rows(out)
    mine = [r for r in rows if int(r["index"]) == 0]
    assert len(mine) == len(want.segments) and [int(r["segment"]) for r in mine] == list(range(len(mine)))
    for r, s in zip(mine, want.segments):
        assert float(r["start_s"]) == s.start_s and r["outcome"] == s.outcome
        assert (r["max_thrust_N"] == "") == (s.max_thrust_N is None)
    poisoned = [r for r in rows if int(r["index"]) == 2]
    assert len(poisoned) == 1 and poisoned[0]["outcome"] == "failed" and poisoned[0]["segment"] == ""
    assert {int(r["index"]) for r in rows} == {0, 1, 2, 3}


def test_parquet_without_pyarrow_is_refused_before_any_fit(fleet, tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pyarrow", None)  # `import pyarrow` raises ImportError
    out = tmp_path / "fleet.parquet"
    with pytest.raises(DataError, match="pyarrow"):
        FleetWriter(out)
    with pytest.raises(DataError, match="pyarrow") as e:  # refused before any fit
        fit_many(fleet, LIGHT, out=out, progress=False)
    assert str(out) in str(e.value) and ".csv" in str(e.value)
    assert not out.exists()


def test_parquet_holds_the_csv_rows(fleet, serial, tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    out, out_csv = tmp_path / "fleet.parquet", tmp_path / "fleet.csv"
    fit_many(fleet, LIGHT, out=out, progress=False)
    fit_many(fleet, LIGHT, out=out_csv, progress=False)
    table = pq.read_table(out)
    assert table.column_names == list(FLEET_COLUMNS)
    rows = table.to_pylist()
    assert sorted(r["index"] for r in rows) == [0, 1, 2, 3]
    by_csv = {int(r["index"]): r for r in _rows(out_csv)}
    for r in rows:
        c = by_csv[r["index"]]
        for k in FLEET_COLUMNS:
            if c[k] == "":
                assert r[k] is None, k  # an empty CSV cell is a Parquet null, never NaN
            elif isinstance(r[k], float):
                assert r[k] == pytest.approx(float(c[k]), rel=1e-12), k
            else:
                assert str(r[k]) == c[k], k
    bad = next(r for r in rows if "poisoned" in r["source"])
    assert bad["outcome"] == "failed" and bad["max_thrust_N"] is None and "row 7" in bad["reason"]
    _check_rows(by_csv.values(), fleet, serial)


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_cli_fleet_writes_the_rows_and_exits_1_for_the_poisoned_log(fleet, serial, tmp_path, capsys):
    from soiltrack.cli import main

    out = tmp_path / "cli.csv"
    rc = main(["fleet", *fleet, "--vehicle", "light", "--out", str(out), "--workers", "2"])
    cap = capsys.readouterr()
    assert rc == 1 and "4 logs" in cap.out and "1 failed" in cap.out
    assert "poisoned.csv" in cap.err and "row 7" in cap.err
    _check_rows(_rows(out), fleet, serial)
    assert main(["fleet", *fleet, "--vehicle", "light", "--out", str(out), "--segments", "soon"]) == 2
    assert main(["fleet", *fleet, "--vehicle", "light", "--out", str(tmp_path / "x.parquet")]) in (
        (0, 1) if _has_pyarrow() else (2,)
    )
    assert "Traceback" not in capsys.readouterr().err


def _has_pyarrow():
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.skipif(FORK is None, reason="needs the fork start method")
def test_rows_are_written_in_the_order_the_fits_finish(fleet, tmp_path):
    """A log that fails at once (the poisoned one, last in the input) has its row before a long fit's."""
    out = tmp_path / "order.csv"
    with ProcessPoolExecutor(2, mp_context=FORK) as ex:
        fit_many([fleet[0], fleet[2]], LIGHT, executor=ex, chunk_size=1, out=out, progress=False)
    assert [int(r["index"]) for r in _rows(out)] == [1, 0]
