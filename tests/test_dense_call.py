"""call_dense: the buffer-interface evaluation gives the plain call's numbers, shapes and errors."""

from __future__ import annotations

import threading

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from soiltrack.soilmodel.dense_call import call_dense


def _kernel(p: int, rows: int) -> ca.Function:
    th = ca.SX.sym("th", p)
    s = ca.SX.sym("s")
    d = ca.SX.sym("d", rows)
    e = ca.vertcat(ca.exp(th[0] * s) - d[0], ca.sum1(th) * ca.sin(d[rows - 1]))
    return ca.Function("k", [th, s, d], [e, ca.sumsqr(e), ca.densify(ca.jacobian(e, th))])


@settings(max_examples=25, deadline=None)
@given(p=st.integers(1, 4), rows=st.integers(1, 5), n=st.integers(1, 40), seed=st.integers(0, 2**31 - 1))
def test_mapped_kernel_equals_plain_call(p: int, rows: int, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    f = _kernel(p, rows).map(n)
    th = rng.normal(size=(p, 1))  # one column, repeated over the samples as a plain call repeats it
    s = rng.normal(size=(1, n))
    D = rng.normal(size=(rows, n))
    plain = [np.asarray(o, dtype=float) for o in f(th, s, D)]
    assert all(f.nnz_out(i) == f.numel_out(i) for i in range(f.n_out()))  # the buffer path, not the fallback
    fast = call_dense(f, th, s, D)
    assert len(fast) == len(plain)
    for a, b in zip(fast, plain):
        assert a.shape == b.shape
        np.testing.assert_array_equal(a, b)


def test_scalar_broadcast_and_flat_inputs() -> None:
    x = ca.SX.sym("x", 2, 3)
    y = ca.SX.sym("y")
    f = ca.Function("f", [x, y], [x * y, ca.sum2(x)])
    X = np.arange(6.0).reshape(2, 3)
    out = call_dense(f, X.ravel(), 2.0)  # row-major flat, as np.reshape reads it
    np.testing.assert_array_equal(out[0], 2 * X)
    np.testing.assert_array_equal(out[1], X.sum(axis=1, keepdims=True))


def test_sparse_output_falls_back_to_the_plain_call() -> None:
    x = ca.SX.sym("x", 3)
    f = ca.Function("f", [x], [ca.diag(x)])  # a sparse 3 x 3 output
    out = call_dense(f, np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(out[0], np.diag([1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="input 0 has 2 values"):  # checked before the fallback too
        call_dense(f, np.zeros(2))


def test_wrong_inputs_are_named() -> None:
    f = _kernel(2, 3)
    with pytest.raises(ValueError, match="3 inputs given, 2 expected|2 inputs given, 3 expected"):
        call_dense(f, np.zeros(2), np.zeros(1))
    with pytest.raises(ValueError, match="input 2 has 5 values"):
        call_dense(f, np.zeros(2), np.zeros(1), np.zeros(5))


def test_threads_do_not_share_buffers() -> None:
    f = _kernel(3, 2).map(500)
    rng = np.random.default_rng(0)
    cases = [(rng.normal(size=(3, 1)), rng.normal(size=(1, 500)), rng.normal(size=(2, 500))) for _ in range(8)]
    expected = [[np.asarray(o, dtype=float) for o in f(*c)] for c in cases]
    got: dict[int, list[np.ndarray]] = {}

    def work(i: int) -> None:
        for _ in range(20):
            got[i] = call_dense(f, *cases[i])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(len(cases))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i, exp in enumerate(expected):
        for a, b in zip(got[i], exp):
            np.testing.assert_array_equal(a, b)
