"""The on-line kernels at ``-O3`` give the numbers of ``-O2`` bit for bit (jitcache.FLAGS_O3, kernels.KERNEL_FLAGS).

``-O3`` may inline, unroll and vectorise, never reassociate (no unsafe floating-point options;
``-ffp-contract=off``: no fused multiply-adds). Checked here on an estimator's own buffers, every kernel.
"""

from __future__ import annotations

import numpy as np
import pytest

from online_oracle import SOILS, simulate
from soiltrack.identify import OnlineEstimator, OnlineSettings, jitcache
from soiltrack.identify.online import kernels as K
from soiltrack.identify.online.ccall import BufferCall
from soiltrack.soilmodel import VEHICLES

KEYS = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s")


def _states(n_stop=(25, 40, 55)):
    """Estimator buffers of capacity 64 part-way through a light-vehicle pull (seed 4901: not used elsewhere)."""
    log = simulate("light", lambda t: SOILS["lete_sand"], 1.2, [(0.3, 0.9, 0.95)], seed=4901)
    est = OnlineEstimator(VEHICLES["light"], OnlineSettings())
    out = []
    for k, row in enumerate(zip(*(log[c] for c in KEYS))):
        est.update(*row)
        if k in n_stop:
            assert est._cap == 64
            out.append(_inputs(est))
    return out


def _inputs(est):
    """Copies of the inputs of the six kernels, in kernel_functions order."""
    D, Z, P, noise = est._D.copy(), est._Z.copy(), est._P.copy(), est._noise.copy()
    raw, RAW = est._RAW[0].copy(), est._RAW.copy()
    V = np.array([1e-3, 1e-5, 1e-4])
    row = D[int(np.argmax(D[:, K.ROWS.index("m")]))].copy()
    return [[D, Z, P], [D, Z, P], [row, P], [raw, noise], [RAW, noise], [row, P, V]]


def _outputs(fn):
    return [np.zeros((fn.size2_out(j), fn.size1_out(j))).reshape(-1) for j in range(fn.n_out())]


def test_kernels_at_O3_give_the_numbers_of_O2_bit_for_bit():
    if jitcache.compiler() is None:
        pytest.skip("no C compiler")
    assert K.KERNEL_FLAGS == jitcache.FLAGS_O3 and jitcache.FLAGS_O3[0] == "-O3"
    assert jitcache.FLAGS_O3[1:] == jitcache.FLAGS[1:] and "-ffp-contract=off" in jitcache.FLAGS_O3
    fns = K.kernel_functions(64)
    libs = {}
    for flags in (jitcache.FLAGS, jitcache.FLAGS_O3):
        comp = jitcache.load(fns, K.library_name(64), wait=True, flags=flags)
        assert comp.is_c, comp.backend
        libs[flags[0]] = comp.path
    assert libs["-O2"] != libs["-O3"]  # the flags are part of the cache key
    n_checked = 0
    for state in _states():
        for fn, ins in zip(fns, state):
            res = {}
            for opt, path in libs.items():
                outs = _outputs(fn)
                BufferCall(fn, path, [a.copy() for a in ins], outs)()
                res[opt] = outs
            for a, b in zip(res["-O2"], res["-O3"]):
                assert np.all(np.isfinite(a))
                assert np.array_equal(a, b), fn.name()
            n_checked += 1
    assert n_checked == 18
