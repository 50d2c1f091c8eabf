"""The compiled-code cache: the right backend label, no temporary files on a failed write, the fallback
said once on stderr and in the report (issue 23, item 3)."""

import errno
import json
import os
import subprocess
import sys

import casadi as ca
import pytest

from soiltrack.identify import jitcache

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _functions(tag: str):
    x = ca.SX.sym("x")
    return [ca.Function(f"reltest_{tag}", [x], [x * x + 1])]


@pytest.fixture
def fresh(monkeypatch):
    monkeypatch.setattr(jitcache, "_SAID", set())
    monkeypatch.delenv("SOILTRACK_NO_JIT", raising=False)
    return monkeypatch


def test_unwritable_cache_is_not_reported_as_no_compiler(tmp_path, fresh, capsys):
    if jitcache.compiler() is None:
        pytest.skip("needs a C compiler")
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    fresh.setenv("SOILTRACK_CACHE_DIR", str(blocker / "cache"))
    c1 = jitcache.load(_functions("unwritable"), "reltest_unwritable")
    c2 = jitcache.load(_functions("unwritable2"), "reltest_unwritable2")
    assert c1.backend == c2.backend == jitcache.VM_UNWRITABLE
    assert float(c1.functions[0](3.0)) == 10.0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1  # said once per process


def test_no_compiler_label(tmp_path, fresh, capsys):
    fresh.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))
    fresh.setenv("CC", "/no/such/compiler")
    c = jitcache.load(_functions("nocc"), "reltest_nocc")
    assert c.backend == jitcache.VM_NO_CC
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_a_cached_library_in_a_read_only_folder_still_loads(tmp_path, fresh):
    if jitcache.compiler() is None:
        pytest.skip("needs a C compiler")
    fresh.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))
    assert jitcache.load(_functions("ro"), "reltest_ro").backend == jitcache.C_NEW
    fresh.setattr(jitcache, "cache_writable", lambda: (False, "read-only for this test"))
    c = jitcache.load(_functions("ro"), "reltest_ro")
    assert c.backend == jitcache.C_CACHED and float(c.functions[0](2.0)) == 5.0


def test_a_failed_write_leaves_no_temporary_file(tmp_path, fresh, capsys):
    if jitcache.compiler() is None:
        pytest.skip("needs a C compiler")
    fresh.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))

    class Full:
        def __init__(self, fd, mode):
            os.close(fd)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, text):
            raise OSError(errno.ENOSPC, "No space left on device")

    fresh.setattr(jitcache.os, "fdopen", Full)
    c = jitcache.load(_functions("full"), "reltest_full")
    assert c.backend == jitcache.VM_FAILED
    assert os.listdir(tmp_path) == []
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


@pytest.mark.slow
def test_the_report_says_the_fallback(tmp_path):
    env = dict(os.environ, SOILTRACK_CACHE_DIR=str(tmp_path / "nofolder"), PYTHONPATH=ROOT)
    (tmp_path / "nofolder").write_text("")  # a file where the cache folder should be
    csv_path = tmp_path / "sweep.csv"  # loads 150 and 450 N: the compiled engine (not profile intervals)
    subprocess.run(
        [
            sys.executable,
            "-m",
            "soiltrack",
            "simulate",
            "--kind",
            "sweep",
            "--vehicle",
            "light",
            "--terrain",
            "sandy_loam",
            "--loads",
            "150,450",
            "--seed",
            "1",
            "-o",
            str(csv_path),
        ],
        env=env,
        check=True,
        capture_output=True,
        timeout=300,
    )
    out = subprocess.run(
        [sys.executable, "-m", "soiltrack", "fit", str(csv_path), "--vehicle", "light"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0
    assert len([ln for ln in out.stderr.splitlines() if ln.startswith("soiltrack: ")]) == 1
    assert sum(ln.startswith("engine: ") for ln in out.stdout.splitlines()) == 1
    js = subprocess.run(
        [sys.executable, "-m", "soiltrack", "fit", str(csv_path), "--vehicle", "light", "--json"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert json.loads(js.stdout)["extra"]["engine_backend"] == jitcache.VM_UNWRITABLE
