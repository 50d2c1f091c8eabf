"""Evaluating a CasADi ``Function`` on dense numpy arrays through its buffer interface.

A plain call ``fn(a, b)`` converts every numpy input to a ``DM`` and every output back; for a
mapped kernel over a few thousand samples the output conversion alone (through a Python list of
the elements) costs as much as the evaluation. Measured on the slip-step kernel of a 2,704-sample
drive log (``python benchmarks/bench_dense_call.py``): 3.18 ms per call with the outputs converted,
1.18 ms through the buffer. The buffer interface (``Function.buffer()``) reads and writes the
numpy arrays' memory directly. Each call checks out its own buffer (a few microseconds), so calls
from several threads do not share memory; the numbers are the same operations' as the plain call's.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

__all__ = ["call_dense"]


def _column_major(a: np.ndarray, rows: int, cols: int, name: str, i: int) -> np.ndarray:
    """``a`` as the contiguous column-major array of a ``rows x cols`` matrix (a scalar or one column broadcast)."""
    a = np.asarray(a, dtype=float)
    if a.size == rows * cols:
        m = a.reshape(rows, cols)
    elif a.size == rows and cols > 1:  # one column for every column, as a plain call broadcasts it
        m = np.broadcast_to(a.reshape(rows, 1), (rows, cols))
    elif a.size == 1:
        m = np.broadcast_to(a.reshape(1, 1), (rows, cols))
    else:
        raise ValueError(f"{name}: input {i} has {a.size} values; expected {rows} x {cols}")
    return np.ascontiguousarray(m.T).ravel()


def call_dense(fn: ca.Function, *args: np.ndarray) -> list[np.ndarray]:
    """Evaluate ``fn`` on dense arrays; each output as its ``size1 x size2`` float array.

    Inputs are reshaped to the function's input sizes (row-major numpy order, as ``fn(a)`` reads a
    2-D array); an input of one column (or one value) is repeated over the columns, as a plain call
    does. A function with a sparse input or output is called the plain way.

    Raises
    ------
    ValueError
        Wrong number of inputs, or an input whose size fits neither the input nor one column of it.
    RuntimeError
        The evaluation failed (CasADi's return flag).
    """
    if len(args) != fn.n_in():
        raise ValueError(f"{fn.name()}: {len(args)} inputs given, {fn.n_in()} expected")
    inputs = [_column_major(a, fn.size1_in(i), fn.size2_in(i), fn.name(), i) for i, a in enumerate(args)]
    dense_in = all(fn.nnz_in(i) == fn.numel_in(i) for i in range(fn.n_in()))
    dense_out = all(fn.nnz_out(i) == fn.numel_out(i) for i in range(fn.n_out()))
    if not (dense_in and dense_out):
        out = fn(*(a.reshape(fn.size2_in(i), fn.size1_in(i)).T for i, a in enumerate(inputs)))
        outs = out if isinstance(out, (list, tuple)) else [out]
        return [np.asarray(o, dtype=float) for o in outs]
    buf, trigger = fn.buffer()
    b: Any = buf  # casadi's type stubs give set_arg/set_res a size argument its Python wrapper does not take
    for i, a in enumerate(inputs):
        b.set_arg(i, a.data)  # ndarray.data: a memoryview of the array's memory
    flat = [np.empty(fn.numel_out(i)) for i in range(fn.n_out())]
    for i, o in enumerate(flat):
        b.set_res(i, o.data)
    trigger()
    if buf.ret() != 0:
        raise RuntimeError(f"{fn.name()}: evaluation failed (return flag {buf.ret()})")
    return [o.reshape(fn.size2_out(i), fn.size1_out(i)).T for i, o in enumerate(flat)]
