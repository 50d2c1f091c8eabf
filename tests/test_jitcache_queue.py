"""Queued background compilations (jitcache.load(queue=True)): one at a time per cache folder."""

from __future__ import annotations

import fcntl
import os
import shutil
import time

import casadi as ca
import numpy as np
import pytest

from soiltrack.identify import jitcache


def _fn(tag: str) -> ca.Function:
    x = ca.SX.sym("x", 3)
    return ca.Function(f"queued_{tag}", [x], [ca.sin(x) * ca.exp(x[0]) + len(tag)])


def _libs(folder) -> list[str]:
    return [f for f in os.listdir(folder) if f.endswith(".so")]


def test_queued_compilation_waits_for_the_lock_then_loads(tmp_path, monkeypatch):
    if jitcache.compiler() is None or shutil.which("flock") is None:
        pytest.skip("needs a C compiler and flock")
    monkeypatch.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))
    lock = tmp_path / jitcache.COMPILE_LOCK
    with open(lock, "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # another queued compilation running
        c = jitcache.load([_fn("a")], "queued_test", wait=False, queue=True)
        assert c.backend == jitcache.VM_PENDING and not c.is_c
        time.sleep(1.5)  # ample for this small library, were it not queued
        assert _libs(tmp_path) == [] and not c.upgrade()
    deadline = time.time() + 120
    while not _libs(tmp_path) and time.time() < deadline:
        time.sleep(0.1)
    assert len(_libs(tmp_path)) == 1
    assert c.upgrade() and c.is_c and c.backend == jitcache.C_CACHED
    x = np.array([0.3, -0.2, 1.1])
    assert np.array_equal(np.asarray(c.functions[0](x)).ravel(), np.asarray(_fn("a")(x)).ravel())


def test_unqueued_compilation_ignores_the_lock(tmp_path, monkeypatch):
    if jitcache.compiler() is None:
        pytest.skip("needs a C compiler")
    monkeypatch.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))
    with open(tmp_path / jitcache.COMPILE_LOCK, "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        c = jitcache.load([_fn("b")], "unqueued_test", wait=False)
        assert c.backend == jitcache.VM_PENDING
        deadline = time.time() + 120
        while not _libs(tmp_path) and time.time() < deadline:
            time.sleep(0.1)
        assert len(_libs(tmp_path)) == 1 and c.upgrade() and c.is_c
