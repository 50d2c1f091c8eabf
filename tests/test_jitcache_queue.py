"""Deferred background compilations (jitcache.load(defer=True)): started at exit, one at a time per cache folder."""

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


@pytest.mark.slow
def test_deferred_compilation_starts_at_exit_waits_for_the_lock_then_loads(tmp_path, monkeypatch):
    if jitcache.compiler() is None or shutil.which("flock") is None:
        pytest.skip("needs a C compiler and flock")
    monkeypatch.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(jitcache, "_DEFERRED", {})  # none deferred by earlier tests
    lock = tmp_path / jitcache.COMPILE_LOCK
    c = jitcache.load([_fn("a")], "queued_test", wait=False, defer=True)
    assert c.backend == jitcache.VM_PENDING and not c.is_c
    time.sleep(1.0)  # ample for this small library, were it compiled now
    assert _libs(tmp_path) == [] and not c.upgrade()
    with open(lock, "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # another queued compilation running
        assert jitcache.start_deferred() == 1  # what atexit does
        assert jitcache.start_deferred() == 0
        time.sleep(1.0)
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


def test_deferred_compilation_skips_a_library_made_meanwhile(tmp_path, monkeypatch):
    # two processes deferred the same library: the second queued compilation finds it and does nothing
    if jitcache.compiler() is None or shutil.which("flock") is None:
        pytest.skip("needs a C compiler and flock")
    monkeypatch.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(jitcache, "_DEFERRED", {})  # none deferred by earlier tests
    c = jitcache.load([_fn("c")], "skip_test", wait=False, defer=True)
    lib = c.path
    assert lib is not None
    with open(tmp_path / jitcache.COMPILE_LOCK, "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert jitcache.start_deferred() == 1
        with open(lib, "w") as fh:  # "made by another process" (a placeholder the compiler must not replace)
            fh.write("made meanwhile")
    deadline = time.time() + 60
    while [f for f in os.listdir(tmp_path) if f.endswith(".c")] and time.time() < deadline:
        time.sleep(0.1)
    assert not [f for f in os.listdir(tmp_path) if f.endswith((".c", ".tmp"))]
    with open(lib) as fh:
        assert fh.read() == "made meanwhile"
