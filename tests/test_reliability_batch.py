"""fit_many loses nothing, and a fork beside solver threads never hangs (issue 23, items 1 and 2)."""

import multiprocessing as mp
import os
import subprocess
import sys
import textwrap
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest

from soiltrack.identify import fit, fit_many
from soiltrack.soilmodel import TERRAINS, VEHICLES, DriveLog, SlipData
from soiltrack.soilmodel.simulation import simulate

LIGHT = VEHICLES["light"]
PARENT = os.getpid()
HAS_FORK = "fork" in mp.get_all_start_methods()


def _rebuild(parent: int, marker: str | None, slip, force, load) -> SlipData:
    """Unpickled in a worker: kills it (always, or only the first time when ``marker`` is given)."""
    if os.getpid() != parent:
        if marker is None:
            os._exit(7)
        if not os.path.exists(marker):
            open(marker, "w").close()
            os._exit(7)
    return SlipData(slip, force, load)


class Killer(SlipData):
    """A sweep whose unpickling kills the worker process (a crash, an out-of-memory kill)."""

    marker = None

    def __reduce__(self):
        return (_rebuild, (PARENT, self.marker, self.slip, self.values, self.normal_load))


def _sweeps(n: int) -> list[SlipData]:
    # loads 150 and 450 N: a spread that fit solves with the compiled kernel, as fit_many stacks it
    return [simulate(LIGHT, TERRAINS["sandy_loam"], kind="sweep", seed=s, normal_loads=[150, 450]) for s in range(n)]


@pytest.fixture(scope="module")
def poisoned():
    items: list = list(_sweeps(24))
    bad = {
        3: None,
        7: SlipData([0.1], [50.0], [300.0]),
        12: "sweep.csv",
        18: DriveLog([0.0, 1.0], [1.0, 1.0], [1.0, 1.0], [0.1, 0.1]),
    }
    for k, v in bad.items():
        items[k] = v
    return items, set(bad)


def _same(a, b) -> bool:
    return a.success == b.success and np.array_equal(a.theta, b.theta) and a.status == b.status


def test_poisoned_batch_gives_one_result_per_item_in_order(poisoned):
    items, bad = poisoned
    res = fit_many(items, LIGHT, progress=False)
    assert len(res) == len(items)
    engines = {res[k].extra["engine"] for k in range(len(items)) if k not in bad}
    assert engines <= {"vectorized", "vectorized-vm"}  # the stacked kernel, not fit one by one
    for k, (d, r) in enumerate(zip(items, res)):
        if k in bad:
            assert r.success is False and r.status == "not fitted" and r.extra["batch_index"] == k
            assert r.message.startswith(f"batch item {k} ")
        else:
            assert _same(r, fit(d, LIGHT))


def test_thread_pool_gives_the_same(poisoned):
    items, bad = poisoned
    serial = fit_many(items, LIGHT, progress=False)
    with ThreadPoolExecutor(2) as ex:
        res = fit_many(items, LIGHT, progress=False, executor=ex, chunk_size=5)
    assert [r.success for r in res] == [r.success for r in serial]
    assert all(_same(a, b) for k, (a, b) in enumerate(zip(res, serial)) if k not in bad)


def test_strict_raises_after_the_batch(poisoned):
    from soiltrack.identify import FitFailed

    with pytest.raises(FitFailed):
        fit_many(poisoned[0], LIGHT, progress=False, strict=True)


def test_repeated_rows_are_said_and_counted():
    d = _sweeps(1)[0]
    idx = np.r_[np.arange(d.n_samples), [2, 5, 5]]
    rep = d.subset(idx)
    for r in (fit(rep, LIGHT), fit_many([rep], LIGHT, progress=False)[0]):
        found = {f["check"]: f for f in r.extra["consistency"]["findings"]}
        assert found["repeated_rows"]["count"] == 3
        assert found["repeated_rows"]["rows"] == [d.n_samples + 1, d.n_samples + 2, d.n_samples + 3]
        assert found["repeated_rows"]["severity"] == "warning"


@pytest.mark.skipif(not HAS_FORK, reason="needs the fork start method")
@pytest.mark.slow
def test_a_worker_killed_by_an_item_costs_only_that_item():
    items: list = list(_sweeps(16))
    d = items[5]
    items[5] = Killer(d.slip, d.values, d.normal_load)
    serial = fit_many(items, LIGHT, progress=False)  # in this process the item is harmless
    with ProcessPoolExecutor(2, mp_context=mp.get_context("fork")) as ex:
        res = fit_many(items, LIGHT, progress=False, executor=ex, chunk_size=4)
    assert len(res) == len(items)
    assert res[5].success is False and res[5].extra["error"] == "BrokenProcessPool"
    assert res[5].extra["batch_index"] == 5
    assert all(_same(a, b) for k, (a, b) in enumerate(zip(res, serial)) if k != 5)


@pytest.mark.skipif(not HAS_FORK, reason="needs the fork start method")
@pytest.mark.slow
def test_a_worker_that_dies_once_has_its_items_retried(tmp_path):
    items: list = list(_sweeps(12))
    d = items[4]
    k = Killer(d.slip, d.values, d.normal_load)
    object.__setattr__(k, "marker", str(tmp_path / "died"))
    items[4] = k
    serial = fit_many(items, LIGHT, progress=False)
    with ProcessPoolExecutor(2, mp_context=mp.get_context("fork")) as ex:
        res = fit_many(items, LIGHT, progress=False, executor=ex, chunk_size=3)
    assert os.path.exists(tmp_path / "died")  # the worker did die
    assert [r.success for r in res] == [True] * len(items)
    assert all(_same(a, b) for a, b in zip(res, serial))


FORK_BESIDE_IPOPT = textwrap.dedent("""
    import multiprocessing as mp, sys, threading, time
    from concurrent.futures import ProcessPoolExecutor, wait
    from soiltrack.identify import fit
    from soiltrack.soilmodel import TERRAINS, VEHICLES
    from soiltrack.soilmodel.simulation import simulate

    veh = VEHICLES["light"]
    data = simulate(veh, TERRAINS["sandy_loam"], kind="sweep", seed=1, normal_loads=[300, 450])

    def job(k):
        return fit(data, veh, engine=sys.argv[1]).success

    def spin(stop):
        while not stop.is_set():
            fit(data, veh, engine="ipopt")

    fit(data, veh, engine="ipopt")
    finished = 0
    for attempt in range(5):
        stop = threading.Event()
        threads = [threading.Thread(target=spin, args=(stop,), daemon=True) for _ in range(3)]
        for t in threads:
            t.start()
        time.sleep(0.3)
        with ProcessPoolExecutor(2, mp_context=mp.get_context("fork")) as ex:
            futs = [ex.submit(job, k) for k in range(4)]
            done, pending = wait(futs, timeout=60)
            stop.set()
            if pending:
                for p in ex._processes.values():
                    p.kill()
                print("HUNG", attempt, flush=True)
                sys.exit(3)
            finished += all(f.result() for f in done)
        for t in threads:
            t.join()
    print("FINISHED", finished, flush=True)
""")


@pytest.mark.skipif(not HAS_FORK, reason="needs the fork start method")
@pytest.mark.slow
@pytest.mark.parametrize("engine", ["ipopt", "auto"])
def test_fork_pool_beside_threads_running_ipopt_finishes_five_times(engine):
    out = subprocess.run([sys.executable, "-c", FORK_BESIDE_IPOPT, engine], capture_output=True, text=True, timeout=400)
    assert out.returncode == 0, out.stdout + out.stderr[-2000:]
    assert out.stdout.split()[-2:] == ["FINISHED", "5"]


class FlakyExecutor(ThreadPoolExecutor):
    """A thread pool whose first submitted chunk is lost (as a Dask worker dying would lose it)."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.lost = 0

    def submit(self, fn, /, *args, **kwargs):
        if self.lost == 0:
            self.lost += 1
            from concurrent.futures import Future

            fut = Future()
            fut.set_exception(RuntimeError("worker lost"))
            return fut
        return super().submit(fn, *args, **kwargs)


def test_a_chunk_lost_by_another_executor_is_retried_item_by_item():
    items = _sweeps(10)
    serial = fit_many(items, LIGHT, progress=False)
    with FlakyExecutor(2) as ex:
        res = fit_many(items, LIGHT, progress=False, executor=ex, chunk_size=4)
    assert ex.lost == 1
    assert [r.success for r in res] == [True] * len(items)
    assert all(_same(a, b) for a, b in zip(res, serial))
