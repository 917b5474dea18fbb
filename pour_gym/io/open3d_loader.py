"""Import open3d on machines that lack the system libusb it links against.

open3d's wheels link ``libusb-1.0.so.0``, which minimal Linux images (containers, CI) do not
have. The ``libusb-package`` wheel ships that library; loading it first with global symbol
visibility lets the dynamic linker resolve open3d's dependency by its soname.
"""

from __future__ import annotations

import ctypes
import importlib
from types import ModuleType

_open3d: ModuleType | None = None


def open3d() -> ModuleType:
    """Return the imported ``open3d`` module, preloading libusb if the system has none."""
    global _open3d  # a module cache, not state: importing twice would give the same module
    if _open3d is not None:
        return _open3d
    # open3d brings a TBB too old for numba: the tbb wheel's must be the process's first.
    from pour_gym.io.numba_threads import use_wheel_tbb

    use_wheel_tbb()
    try:
        _open3d = importlib.import_module("open3d")
    except ImportError as exc:
        if "libusb" not in str(exc):
            raise
        import libusb_package

        ctypes.CDLL(str(libusb_package.get_library_path()), mode=ctypes.RTLD_GLOBAL)
        _open3d = importlib.import_module("open3d")
    # open3d logs warnings to stdout, which must stay clean for --json output.
    _open3d.utility.set_verbosity_level(_open3d.utility.VerbosityLevel.Error)
    return _open3d
