"""Compiled CasADi Functions in a per-user on-disk cache (C code generated once per machine).

The compiled engines generate C code from CasADi Functions (:mod:`soiltrack.identify.sweep.compiled_lm`).
Compiling it costs about a second; this module makes that a once-per-machine cost:

* The generated source is hashed (SHA-256 of the source, the CasADi version, the compiler
  and its flags); the shared library is stored as ``<cache>/<name>_<hash>.so``. A second
  process that generates the same source finds the library and loads it: no compilation.
* ``<cache>`` is ``$SOILTRACK_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/soiltrack``, else
  ``~/.cache/soiltrack``. Libraries are written atomically (compiled to a unique temporary
  name in the same folder, then renamed), so concurrent processes never load a half-written
  file; if two compile the same source, one rename wins and both results are identical.
* Without a C compiler (none on ``PATH``, ``$CC`` empty) or with ``SOILTRACK_NO_JIT`` set,
  nothing is compiled: the caller keeps CasADi's virtual machine (same Function, same
  numbers, a few times slower) and says so (:func:`load` returns the backend it used).

:func:`load` can also compile in the background: it returns the virtual machine at once and
starts a detached, low-priority compiler process that writes the library into the cache
(it finishes even if this process exits first), so that later calls - in this process, via
:meth:`Compiled.upgrade`, or in the next one - use the C code. This is what the default
``engine="auto"`` does: no call ever waits for a compiler, and the compile cliff disappears.
"""
from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import subprocess
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import casadi as ca

__all__ = ["cache_dir", "compiler", "load", "Compiled", "FLAGS"]

#: Compiler flags of every cached library. Only the entry points CasADi marks for export are
#: visible (``-fvisibility=hidden`` with CasADi's ``GCC_HASCLASSVISIBILITY``), so the compiler may
#: inline the generated helpers (``casadi_sq``, ``casadi_copy``, ...) instead of calling them
#: through the PLT: the same operations in the same order, about a third less time per call.
#: ``-ffp-contract=off``: no fused multiply-adds, whatever the target (the IEEE operations as written).
FLAGS = ("-O2", "-fvisibility=hidden", "-DGCC_HASCLASSVISIBILITY", "-ffp-contract=off", "-shared", "-fPIC")

#: Backend labels (``Compiled.backend``).
C_CACHED, C_NEW, VM_NO_CC, VM_PENDING, VM_FAILED, VM_OFF = (
    "C (disk cache)", "C (compiled now)", "virtual machine (no C compiler)",
    "virtual machine (C code compiling in the background)", "virtual machine (C compilation failed)",
    "virtual machine (JIT off: SOILTRACK_NO_JIT or jit='off')")

_LOCK = threading.Lock()  # guards the dicts below
_LIB_LOCKS: dict[str, threading.Lock] = {}  # one per library: one compilation of it per process at a time
_PENDING: dict[str, subprocess.Popen] = {}


def _after_fork() -> None:  # a lock held by another thread at fork time would never be released
    global _LOCK
    _LOCK = threading.Lock()
    _LIB_LOCKS.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)


def cache_dir() -> Path:
    """The per-user folder of compiled libraries (created on first use)."""
    d = os.environ.get("SOILTRACK_CACHE_DIR")
    if not d:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        d = os.path.join(base, "soiltrack")
    p = Path(d)
    p.mkdir(parents=True, exist_ok=True)
    return p


def compiler() -> str | None:
    """The C compiler to use (``$CC``, else ``cc``/``gcc`` on ``PATH``), or ``None``."""
    if os.environ.get("SOILTRACK_NO_JIT"):
        return None
    cc = os.environ.get("CC")
    if cc is not None:
        return shutil.which(cc.split()[0]) and cc or None
    for name in ("cc", "gcc", "clang"):
        if shutil.which(name):
            return name
    return None


@dataclass
class Compiled:
    """A group of Functions generated from one source, with the backend that evaluates them.

    ``functions`` are the virtual-machine Functions until the C library is loaded;
    ``backend`` is one of the labels above. :meth:`upgrade` swaps in the C library once a
    background compilation has finished (cheap to call often: one ``stat``).
    """

    names: tuple[str, ...]
    functions: list
    backend: str
    path: str | None = None
    _checked: int = field(default=0, repr=False)

    @property
    def is_c(self) -> bool:
        """True when the C library evaluates the Functions."""
        return self.backend in (C_CACHED, C_NEW)

    def upgrade(self) -> bool:
        """Load the C library if a background compilation has produced it; True if it did."""
        if self.backend != VM_PENDING or self.path is None:
            return False
        if not os.path.exists(self.path):
            proc = _PENDING.get(self.path)
            if proc is not None and proc.poll() not in (None, 0):
                self.backend = VM_FAILED
            return False
        try:
            self.functions = [ca.external(n, self.path) for n in self.names]
        except Exception:  # noqa: BLE001 - a broken library: keep the virtual machine
            self.backend = VM_FAILED
            return False
        self.backend = C_CACHED
        return True


def _source(functions: Sequence[ca.Function], name: str) -> str:
    cg = ca.CodeGenerator(name + ".c", {"with_header": False})
    for f in functions:
        cg.add(f)
    return cg.dump()


def _library_path(source: str, name: str, cc: str) -> Path:
    h = hashlib.sha256()
    for part in (source, ca.__version__, cc, " ".join(FLAGS)):
        h.update(part.encode())
        h.update(b"\0")
    return cache_dir() / f"{name}_{h.hexdigest()[:24]}.so"


def _write_source(folder: Path, name: str, source: str) -> str:
    fd, src = tempfile.mkstemp(prefix=name + "_", suffix=".c", dir=folder)
    with os.fdopen(fd, "w") as fh:
        fh.write(source)
    return src


def _compile_now(source: str, name: str, cc: str, lib: Path) -> bool:
    src = _write_source(lib.parent, name, source)
    tmp = f"{lib}.{os.getpid()}.{threading.get_ident()}.tmp"
    try:
        done = subprocess.run(shlex.split(cc) + list(FLAGS) + [src, "-o", tmp, "-lm"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, check=False)
        if done.returncode != 0 or not os.path.exists(tmp):
            return False
        os.replace(tmp, lib)  # atomic: readers see the old state or the whole library
        return True
    finally:
        for f in (src, tmp):
            if os.path.exists(f):
                os.remove(f)


def _compile_background(source: str, name: str, cc: str, lib: Path) -> None:
    if str(lib) in _PENDING and _PENDING[str(lib)].poll() is None:
        return
    src = _write_source(lib.parent, name, source)
    tmp = f"{lib}.{os.getpid()}.bg.tmp"
    cmd = " ".join(shlex.quote(a) for a in shlex.split(cc) + list(FLAGS) + [src, "-o", tmp, "-lm"])
    script = f"{cmd} >/dev/null 2>&1 && mv -f {shlex.quote(tmp)} {shlex.quote(str(lib))}; " \
             f"rm -f {shlex.quote(src)} {shlex.quote(tmp)}"
    argv = (["nice", "-n", "10"] if shutil.which("nice") else []) + ["sh", "-c", script]
    _PENDING[str(lib)] = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL, start_new_session=True)


def load(functions: Sequence[ca.Function], name: str, wait: bool = True) -> Compiled:
    """Evaluate ``functions`` from C code, compiled once per machine (see the module notes).

    Parameters
    ----------
    functions : sequence of casadi.Function
        Functions generated into one C file (names must be distinct).
    name : str
        Prefix of the cached file.
    wait : bool
        ``True``: compile now if the library is not cached yet. ``False``: never wait; if it
        is not cached, return the virtual machine and compile in the background.

    Returns
    -------
    Compiled
        The Functions and the backend that evaluates them.
    """
    names = tuple(f.name() for f in functions)
    vm = Compiled(names, list(functions), VM_NO_CC)
    cc = compiler()
    if cc is None:
        return vm
    try:
        source = _source(functions, name)
        lib = _library_path(source, name, cc)
    except Exception:  # noqa: BLE001 - code generation unavailable: the virtual machine
        return vm
    vm.path = str(lib)
    with _LOCK:
        lock = _LIB_LOCKS.setdefault(str(lib), threading.Lock())
    with lock:
        if not lib.exists():
            if not wait:
                try:
                    _compile_background(source, name, cc, lib)
                except OSError:
                    vm.backend = VM_FAILED
                    return vm
                vm.backend = VM_PENDING
                return vm
            try:
                compiled = _compile_now(source, name, cc, lib)
            except OSError:  # e.g. a read-only cache folder
                compiled = False
            if not compiled:
                vm.backend = VM_FAILED
                return vm
            backend = C_NEW
        else:
            backend = C_CACHED
        try:
            return Compiled(names, [ca.external(n, str(lib)) for n in names], backend, str(lib))
        except Exception:  # noqa: BLE001 - unloadable library: the virtual machine
            vm.backend = VM_FAILED
            return vm
