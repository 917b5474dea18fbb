"""numba's threading layer for pour-gym's parallel loops, and what a forked child may run.

**TBB by default.** numba's TBB threading layer needs TBB 2021.6 or later (interface 12060).
A process has one ``libtbb.so.12``: the first copy loaded is the one every later user gets,
by its soname. open3d's wheel bundles TBB 2021.5 (12050); if open3d is imported first,
numba finds that copy, refuses it, and a parallel kernel told to use TBB raises "No
threading layer could be loaded". So the ``tbb`` wheel's TBB is loaded by whichever comes
first, :mod:`pour_gym.fluid` or :func:`pour_gym.io.open3d_loader.open3d` (pour-gym's only way
to import open3d), and numba is told to use TBB only if the copy the process ended up with
is new enough; otherwise numba chooses (GNU OpenMP, or its workqueue). A user's choice
(``NUMBA_THREADING_LAYER``) is kept.

**GNU OpenMP and fork().** TBB survives ``fork()``; GNU OpenMP does not: a child forked
from a process whose parallel loops ran on it is killed at its own first parallel loop
("fork() called from a process already using GNU OpenMP"). OpenMP is the layer where the
tbb wheel is missing (it is a dependency on Linux x86_64 only) or where the user chose it;
OpenMP's threads spin between loops where TBB's sleep, which on this project's 2-core VM
made Pour-v0 at two threads 1.17x faster (``docs/fluid.md``). So pour-gym's parallel code
asks :func:`threads_usable` first and runs its one-thread build in such a child (the same
numbers), after a warning.

**How many.** :func:`usable_cores`: the processors this process may run on, which the
fluid's default thread count and the benchmarks' record of the machine both start from.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys
import types
from pathlib import Path

SONAME = "libtbb.so.12"
NUMBA_MINIMUM = 12060  # TBB_INTERFACE_VERSION of 2021.6, numba's floor for its TBB layer
FORK_WARNING = (
    "this process was forked from one whose parallel loops ran on GNU OpenMP, which does "
    "not survive fork(): {what} runs on one thread here. Start worker processes with "
    "'forkserver' or 'spawn' to give them threads (or, on Linux x86_64, leave "
    "NUMBA_THREADING_LAYER unset: the tbb wheel's TBB is the default there)."
)


def usable_cores() -> int:
    """Processors this process may run on: its CPU affinity where the OS has one, else all."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, int(cores or 1))


def loaded_version() -> int | None:
    """The interface version of the ``libtbb.so.12`` this process resolves by name, or None."""
    try:
        library = ctypes.CDLL(SONAME)
        version = library.TBB_runtime_interface_version
    except (OSError, AttributeError):
        return None
    version.restype = ctypes.c_int
    return int(version())


@functools.cache
def use_wheel_tbb() -> str | None:
    """Load the wheel's TBB and select numba's TBB layer; the library's path, or None.

    None when not on Linux, when the user chose a threading layer, when there is no wheel
    TBB in this environment, or when another, older TBB was loaded first (open3d imported
    before pour_gym): numba then picks its layer itself.
    """
    if not sys.platform.startswith("linux"):
        return None
    import numba

    if os.environ.get("NUMBA_THREADING_LAYER") or numba.config.THREADING_LAYER != "default":
        return None  # the user chose a layer
    for prefix in dict.fromkeys((sys.prefix, sys.base_prefix)):
        library = Path(prefix) / "lib" / SONAME
        if library.is_file():
            try:
                ctypes.CDLL(str(library), mode=ctypes.RTLD_GLOBAL)
            except OSError:
                return None
            # What numba will load by name: the first copy this process loaded.
            if (loaded_version() or 0) < NUMBA_MINIMUM:
                return None
            numba.config.THREADING_LAYER = "tbb"
            return str(library)
    return None


# Set in a child forked from a process whose parallel loops ran on GNU OpenMP.
_FORKED_FROM_OPENMP = False


def _after_fork_in_child() -> None:
    global _FORKED_FROM_OPENMP  # a fact about this process, which only fork() sets
    numba = sys.modules.get("numba")
    try:
        layer = numba.threading_layer() if numba is not None else None
    except ValueError:  # no parallel loop has run: any layer may start here
        return
    if layer == "omp":
        _FORKED_FROM_OPENMP = True


os.register_at_fork(after_in_child=_after_fork_in_child)


def threads_usable() -> bool:
    """Whether this process may run parallel loops (False in a child forked after OpenMP)."""
    return not _FORKED_FROM_OPENMP


def twin(func: types.FunctionType, suffix: str, namespace: dict | None = None):
    """A copy of a function under another name, to compile it a second way.

    numba caches compilations by a function's name and place: two builds of one function
    (parallel and one-thread, say) need two names.

    Args:
        func: the function.
        suffix: appended to its name.
        namespace: the globals it resolves names in (default: its module's).
    """
    copy = types.FunctionType(
        func.__code__, func.__globals__ if namespace is None else namespace,
        func.__name__ + suffix, func.__defaults__,
    )  # fmt: skip
    copy.__qualname__ = func.__qualname__ + suffix
    copy.__module__ = func.__module__
    copy.__doc__ = func.__doc__
    return copy
