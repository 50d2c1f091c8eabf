"""Calling a compiled CasADi Function on fixed numpy buffers, without per-call conversions.

A CasADi Function called from Python converts every numpy argument to a ``DM`` and every
result back (tens of microseconds for a horizon of a few hundred samples, more than the
computation). The estimator's buffers live for its whole life, so the C entry point of the
generated code (``int f(const double** arg, double** res, long long* iw, double* w, int mem)``)
is called through ctypes on pointers to them, prepared once. Without a C library (no
compiler) the same Function is called the ordinary way, with the same numbers.
"""

from __future__ import annotations

import ctypes

import casadi as ca
import numpy as np

__all__ = ["BufferCall"]


class BufferCall:
    """``fn`` bound to input and output numpy buffers (float64, C-contiguous, column-major shapes).

    Parameters
    ----------
    fn
        The CasADi Function (for sizes and the fallback call).
    library
        Path of the shared library holding ``fn``'s C code, or ``None`` (virtual machine).
    inputs, outputs
        numpy arrays: input ``j`` holds ``fn``'s input ``j`` in column-major order (a matrix
        ``rows x cols`` is an array of shape ``(cols, rows)``); outputs are written in place.
    """

    def __init__(
        self, fn: ca.Function, library: str | None, inputs: list[np.ndarray], outputs: list[np.ndarray]
    ) -> None:
        self.fn, self.inputs, self.outputs = fn, inputs, outputs
        for a in (*inputs, *outputs):
            if a.dtype != np.float64 or not a.flags["C_CONTIGUOUS"]:
                raise ValueError("buffers must be C-contiguous float64 arrays")
        self._c = None
        if library is not None:
            lib = ctypes.CDLL(library)
            c = getattr(lib, fn.name())
            c.restype = ctypes.c_int
            # no ``argtypes``: the arguments are ready-made ctypes objects (no conversion per call)
            self._arg = (ctypes.c_void_p * max(fn.sz_arg(), 1))(*[a.ctypes.data for a in inputs])
            self._res = (ctypes.c_void_p * max(fn.sz_res(), 1))(*[a.ctypes.data for a in outputs])
            self._iw = np.zeros(max(fn.sz_iw(), 1), dtype=np.int64)
            self._w = np.zeros(max(fn.sz_w(), 1), dtype=np.float64)
            self._lib = lib
            self._c = c
            self._args = (
                ctypes.c_void_p(ctypes.addressof(self._arg)),
                ctypes.c_void_p(ctypes.addressof(self._res)),
                ctypes.c_void_p(self._iw.ctypes.data),
                ctypes.c_void_p(self._w.ctypes.data),
                ctypes.c_int(0),
            )
        self._shapes = [(fn.size1_in(j), fn.size2_in(j)) for j in range(fn.n_in())]

    @property
    def compiled(self) -> bool:
        """Whether the C code is called (else CasADi's virtual machine)."""
        return self._c is not None

    def __call__(self) -> None:
        """Evaluate: read the input buffers, write the output buffers."""
        if self._c is not None:
            if self._c(*self._args) != 0:
                raise RuntimeError(f"{self.fn.name()} failed")
            return
        args = [ca.DM(a.reshape(s[1], s[0]).T) for a, s in zip(self.inputs, self._shapes)]
        res = self.fn(*args)
        outs = res if isinstance(res, (list, tuple)) else [res]
        for out, r in zip(self.outputs, outs):
            out[...] = np.asarray(r, dtype=float).T.reshape(out.shape)
