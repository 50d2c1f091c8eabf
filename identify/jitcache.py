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
* A cache folder that cannot be created or written (read-only, another user's) is told apart
  from a missing compiler (:data:`VM_UNWRITABLE`); a write that fails half-way (a full disk)
  leaves no file behind (the temporary source and library are removed).
* A fallback to the virtual machine that the user did not ask for (no compiler, cache not
  writable, compilation failed) is said once per process on stderr (:func:`fallback_note`
  gives the words; the fit report prints them beside the status).

:func:`load` can also compile in the background: it returns the virtual machine at once and
starts a detached, low-priority compiler process that writes the library into the cache
(it finishes even if this process exits first), so that later calls - in this process, via
:meth:`Compiled.upgrade`, or in the next one - use the C code. This is what the default
``engine="auto"`` does: no call ever waits for a compiler, and the compile cliff disappears.
Libraries of secondary gain are loaded with ``defer=True``: their compilation starts when this
process exits (``atexit``), one at a time per cache folder (queued on a lock file with ``flock``,
where the system has it), at the idle scheduling class (``chrt -i 0``; else ``nice -n 19``). The
four libraries per effect structure of a new machine's first diagnosis, compiled at once while it
ran, took the CPU from it (measured on 2 shared cores: 5.3 -> 8.4 s); deferred, the first process
compiles what it did before, and the next ones find the rest in the cache (or pick it up, via
:meth:`Compiled.upgrade`, as soon as another process has compiled it).
"""

from __future__ import annotations

import atexit
import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import casadi as ca

__all__ = [
    "cache_dir",
    "compiler",
    "load",
    "Compiled",
    "FLAGS",
    "FLAGS_O3",
    "fallback_note",
    "FALLBACKS",
    "cache_writable",
    "start_deferred",
    "COMPILE_LOCK",
]

#: Compiler flags of every cached library. Only the entry points CasADi marks for export are
#: visible (``-fvisibility=hidden`` with CasADi's ``GCC_HASCLASSVISIBILITY``), so the compiler may
#: inline the generated helpers (``casadi_sq``, ``casadi_copy``, ...) instead of calling them
#: through the PLT: the same operations in the same order, about a third less time per call.
#: ``-ffp-contract=off``: no fused multiply-adds, whatever the target (the IEEE operations as written).
FLAGS = ("-O2", "-fvisibility=hidden", "-DGCC_HASCLASSVISIBILITY", "-ffp-contract=off", "-shared", "-fPIC")
#: :data:`FLAGS` at ``-O3``, for the libraries whose call time matters (the on-line estimator's kernels,
#: called at every sample): more inlining and unrolling, the same IEEE operations in the same order
#: (``-O3`` enables no unsafe floating-point optimisation, and ``-ffp-contract=off`` stays: no fused
#: multiply-adds), so the same numbers bit for bit (checked on the on-line kernels:
#: tests/test_online_speed_flags.py). The flags are part of a library's cache key.
FLAGS_O3 = ("-O3",) + FLAGS[1:]

#: Lock file (in the cache folder) that serialises queued background compilations (``flock``).
COMPILE_LOCK = ".compile.lock"

#: Backend labels (``Compiled.backend``).
C_CACHED, C_NEW, VM_NO_CC, VM_PENDING, VM_FAILED, VM_OFF, VM_UNWRITABLE = (
    "C (disk cache)",
    "C (compiled now)",
    "virtual machine (no C compiler)",
    "virtual machine (C code compiling in the background)",
    "virtual machine (C compilation failed)",
    "virtual machine (JIT off: SOILTRACK_NO_JIT or jit='off')",
    "virtual machine (compiled-code cache folder not writable)",
)
#: Backends that are a fallback the user did not ask for (said once on stderr and in the report).
FALLBACKS = (VM_NO_CC, VM_FAILED, VM_UNWRITABLE)
_SAID: set[str] = set()  # fallbacks already said on stderr by this process

_LOCK = threading.Lock()  # guards the dicts below
_LIB_LOCKS: dict[str, threading.Lock] = {}  # one per library: one compilation of it per process at a time
_PENDING: dict[str, subprocess.Popen] = {}
# compilations to start at exit (load(defer=True)): source, name, compiler, library, flags
_DEFERRED: dict[str, tuple[str, str, str, Path, tuple[str, ...]]] = {}
_AT_EXIT: list[bool] = []  # start_deferred registered with atexit


def _after_fork() -> None:  # a lock held by another thread at fork time would never be released
    global _LOCK
    _LOCK = threading.Lock()
    _LIB_LOCKS.clear()
    _DEFERRED.clear()  # the parent starts them


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


def cache_writable() -> tuple[bool, str]:
    """``(True, folder)`` when the cache folder exists (or can be made) and is writable, else
    ``(False, why)``."""
    try:
        d = cache_dir()
    except OSError as e:
        return False, f"cannot create the cache folder: {e.strerror or e} ({e.filename or ''})"
    if not os.access(d, os.W_OK | os.X_OK):
        return False, f"the cache folder {d} is not writable"
    return True, str(d)


def fallback_note(backend: str | None, detail: str = "") -> str | None:
    """Words for a fallback backend (``None`` for C, a background compilation or JIT switched off)."""
    if backend not in FALLBACKS:
        return None
    why = {
        VM_NO_CC: "no C compiler found ($CC, cc, gcc, clang)",
        VM_FAILED: "compiling or loading the C code failed",
        VM_UNWRITABLE: "the compiled-code cache folder is not writable (set SOILTRACK_CACHE_DIR to a writable one)",
    }
    return (
        f"compiled engine on CasADi's virtual machine: {why[backend]}"
        + (f" - {detail}" if detail else "")
        + "; the same numbers, a few times slower"
    )


def _say_once(backend: str, detail: str = "") -> None:
    note = fallback_note(backend, detail)
    if note is None:
        return
    with _LOCK:
        if backend in _SAID:
            return
        _SAID.add(backend)
    print(f"soiltrack: {note}", file=sys.stderr, flush=True)


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


def _library_path(source: str, name: str, cc: str, flags: Sequence[str] = FLAGS) -> Path:
    h = hashlib.sha256()
    for part in (source, str(getattr(ca, "__version__", "")), cc, " ".join(flags)):
        h.update(part.encode())
        h.update(b"\0")
    return cache_dir() / f"{name}_{h.hexdigest()[:24]}.so"


def _write_source(folder: Path, name: str, source: str) -> str:
    """The source in a new temporary file; nothing left behind if the write fails (a full disk)."""
    fd, src = tempfile.mkstemp(prefix=name + "_", suffix=".c", dir=folder)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(source)
    except BaseException:
        try:
            os.remove(src)
        except OSError:
            pass
        raise
    return src


def _compile_now(source: str, name: str, cc: str, lib: Path, flags: Sequence[str] = FLAGS) -> bool:
    src = _write_source(lib.parent, name, source)
    tmp = f"{lib}.{os.getpid()}.{threading.get_ident()}.tmp"
    try:
        done = subprocess.run(
            shlex.split(cc) + list(flags) + [src, "-o", tmp, "-lm"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            check=False,
        )
        if done.returncode != 0 or not os.path.exists(tmp):
            return False
        os.replace(tmp, lib)  # atomic: readers see the old state or the whole library
        return True
    finally:
        for f in (src, tmp):
            if os.path.exists(f):
                os.remove(f)


def _compile_background(
    source: str, name: str, cc: str, lib: Path, queue: bool = False, flags: Sequence[str] = FLAGS
) -> None:
    if str(lib) in _PENDING and _PENDING[str(lib)].poll() is None:
        return
    src = _write_source(lib.parent, name, source)
    tmp = f"{lib}.{os.getpid()}.bg.tmp"
    cmd = " ".join(shlex.quote(a) for a in shlex.split(cc) + list(flags) + [src, "-o", tmp, "-lm"])
    script = (
        f"{cmd} >/dev/null 2>&1 && mv -f {shlex.quote(tmp)} {shlex.quote(str(lib))}; "
        f"rm -f {shlex.quote(src)} {shlex.quote(tmp)}"
    )
    if queue:  # its turn may come after another process's queued compilation made the library
        script = f"if [ -e {shlex.quote(str(lib))} ]; then rm -f {shlex.quote(src)}; else {script}; fi"
    # queued: one such compilation at a time per cache folder (flock, where the system has it), at the
    # idle scheduling class (chrt -i: CPU time nobody else wants), else the lowest nice level
    serial = ["flock", str(lib.parent / COMPILE_LOCK)] if queue and shutil.which("flock") else []
    if queue and shutil.which("chrt"):
        prio = ["chrt", "-i", "0"]
    else:
        prio = ["nice", "-n", "19" if queue else "10"] if shutil.which("nice") else []
    argv = prio + serial + ["sh", "-c", script]
    _PENDING[str(lib)] = subprocess.Popen(
        argv,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )


def start_deferred() -> int:
    """Start the deferred background compilations of this process (queued, idle priority); how many.

    Runs at exit (``atexit``); calling it earlier starts them now. A library already in the cache is
    skipped; a compiler that cannot be started is skipped silently (the virtual machine stays).
    """
    with _LOCK:
        jobs = list(_DEFERRED.values())
        _DEFERRED.clear()
    started = 0
    for source, name, cc, lib, flags in jobs:
        if lib.exists():
            continue
        try:
            _compile_background(source, name, cc, lib, queue=True, flags=flags)
        except OSError:
            continue
        started += 1
    return started


def load(
    functions: Sequence[ca.Function],
    name: str,
    wait: bool = True,
    defer: bool = False,
    flags: Sequence[str] = FLAGS,
) -> Compiled:
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
    defer : bool
        With ``wait=False``: the background compilation starts when this process exits, queued
        behind the other deferred ones of the cache folder (``flock`` on :data:`COMPILE_LOCK`),
        at idle priority (see the module notes).
    flags : sequence of str
        Compiler flags (:data:`FLAGS`, or :data:`FLAGS_O3`); part of the library's cache key.

    Returns
    -------
    Compiled
        The Functions and the backend that evaluates them.
    """
    names = tuple(f.name() for f in functions)
    vm = Compiled(names, list(functions), VM_NO_CC)
    cc = compiler()
    if cc is None:
        if not os.environ.get("SOILTRACK_NO_JIT"):
            _say_once(VM_NO_CC)
        return vm
    try:
        source = _source(functions, name)
    except Exception:  # noqa: BLE001 - code generation unavailable: the virtual machine
        vm.backend = VM_FAILED
        _say_once(VM_FAILED, "CasADi's code generator failed")
        return vm
    writable, why = cache_writable()
    flags = tuple(flags)
    try:
        lib = _library_path(source, name, cc, flags)
    except OSError:  # the cache folder cannot be created
        lib = None
    if lib is None or (not writable and not lib.exists()):  # a cached library in a read-only folder still loads
        vm.backend = VM_UNWRITABLE
        _say_once(VM_UNWRITABLE, why)
        return vm
    vm.path = str(lib)
    with _LOCK:
        lock = _LIB_LOCKS.setdefault(str(lib), threading.Lock())
    with lock:
        if not lib.exists():
            if not wait and defer:
                with _LOCK:
                    _DEFERRED.setdefault(str(lib), (source, name, cc, lib, flags))
                    if not _AT_EXIT:
                        atexit.register(start_deferred)
                        _AT_EXIT.append(True)
                vm.backend = VM_PENDING
                return vm
            if not wait:
                try:
                    _compile_background(source, name, cc, lib, flags=flags)
                except OSError as e:
                    vm.backend = VM_FAILED
                    _say_once(VM_FAILED, f"cannot start the compiler: {e.strerror or e}")
                    return vm
                vm.backend = VM_PENDING
                return vm
            try:
                compiled = _compile_now(source, name, cc, lib, flags)
            except OSError as e:  # e.g. a full disk: nothing left behind (_write_source, _compile_now)
                compiled = False
                why = f"writing to the cache failed: {e.strerror or e}"
            else:
                why = "the compiler exited with an error"
            if not compiled:
                vm.backend = VM_FAILED
                _say_once(VM_FAILED, why)
                return vm
            backend = C_NEW
        else:
            backend = C_CACHED
        try:
            return Compiled(names, [ca.external(n, str(lib)) for n in names], backend, str(lib))
        except Exception:  # noqa: BLE001 - unloadable library: the virtual machine
            vm.backend = VM_FAILED
            _say_once(VM_FAILED, f"the cached library {lib} cannot be loaded")
            return vm
