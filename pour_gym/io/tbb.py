"""Load the ``tbb`` wheel's TBB before any other copy, and choose numba's TBB layer with it.

numba's TBB threading layer needs TBB 2021.6 or later (interface 12060). A process has one
``libtbb.so.12``: the first copy loaded is the one every later user gets, by its soname.
open3d's wheel bundles TBB 2021.5 (12050); if open3d is imported first, numba finds that
copy, refuses it, and a parallel kernel told to use TBB raises "No threading layer could
be loaded". So the wheel's TBB is loaded by whichever comes first, :mod:`pour_gym.fluid`
or :func:`pour_gym.io.open3d_loader.open3d` (pour-gym's only way to import open3d), and
numba is told to use TBB only if the copy the process ended up with is new enough;
otherwise numba chooses (OpenMP, or workqueue), and :mod:`pour_gym.fluid` warns before a
fork that OpenMP would not survive.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys
from pathlib import Path

SONAME = "libtbb.so.12"
NUMBA_MINIMUM = 12060  # TBB_INTERFACE_VERSION of 2021.6, numba's floor for its TBB layer


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
