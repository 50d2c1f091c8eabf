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

import weakref
from dataclasses import dataclass
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


@dataclass(frozen=True)
class _Layout:
    """What :func:`call_dense` asks of a function on every call, asked once: input and output sizes and
    whether every input and output is dense."""

    name: str
    ins: tuple[tuple[int, int], ...]
    outs: tuple[tuple[int, int], ...]
    dense: bool


_LAYOUTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _layout(fn: ca.Function) -> _Layout:
    """``fn``'s :class:`_Layout`, kept while ``fn`` lives (the kernels are called thousands of times per fit)."""
    try:
        return _LAYOUTS[fn]
    except (KeyError, TypeError):
        pass
    lay = _Layout(
        fn.name(),
        tuple((fn.size1_in(i), fn.size2_in(i)) for i in range(fn.n_in())),
        tuple((fn.size1_out(i), fn.size2_out(i)) for i in range(fn.n_out())),
        all(fn.nnz_in(i) == fn.numel_in(i) for i in range(fn.n_in()))
        and all(fn.nnz_out(i) == fn.numel_out(i) for i in range(fn.n_out())),
    )
    try:
        _LAYOUTS[fn] = lay
    except TypeError:  # a function object that cannot be referenced weakly: asked again next time
        pass
    return lay


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
    lay = _layout(fn)
    if len(args) != len(lay.ins):
        raise ValueError(f"{lay.name}: {len(args)} inputs given, {len(lay.ins)} expected")
    inputs = [_column_major(a, r, c, lay.name, i) for i, (a, (r, c)) in enumerate(zip(args, lay.ins))]
    if not lay.dense:
        out = fn(*(a.reshape(c, r).T for a, (r, c) in zip(inputs, lay.ins)))
        outs = out if isinstance(out, (list, tuple)) else [out]
        return [np.asarray(o, dtype=float) for o in outs]
    buf, trigger = fn.buffer()
    b: Any = buf  # casadi's type stubs give set_arg/set_res a size argument its Python wrapper does not take
    for i, a in enumerate(inputs):
        b.set_arg(i, a.data)  # ndarray.data: a memoryview of the array's memory
    flat = [np.empty(r * c) for r, c in lay.outs]
    for i, o in enumerate(flat):
        b.set_res(i, o.data)
    trigger()
    if buf.ret() != 0:
        raise RuntimeError(f"{lay.name}: evaluation failed (return flag {buf.ret()})")
    return [o.reshape(c, r).T for o, (r, c) in zip(flat, lay.outs)]
