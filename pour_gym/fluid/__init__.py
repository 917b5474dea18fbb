"""Particle fluid: position-based fluids in numba, colliding with posed containers.

The fluid kernel runs on one thread (compiled without any threading layer) or on several
(numba's parallel loops; see :func:`pour_gym.fluid.pbf.default_threads`). Of numba's
threading layers only TBB and the slow workqueue survive ``fork()``: GNU OpenMP aborts
the children of a process that used it, which is what ``AsyncVectorEnv`` and
``multiprocessing`` do on Linux by default. The ``tbb`` wheel (a dependency on Linux x86_64)
brings a TBB new enough for numba; :mod:`pour_gym.io.tbb` loads it before any other copy
(open3d bundles an older one) and tells numba to use it. Without it the threads run on
OpenMP, and a warning names the fix when such a process forks.
"""

import os
import sys

from pour_gym.io.tbb import use_wheel_tbb

TBB_LIBRARY = use_wheel_tbb()


def _warn_before_fork() -> None:
    try:
        import numba

        layer = numba.threading_layer()
    except (ImportError, ValueError):  # no parallel kernel has run yet: forking is safe
        return
    if layer == "omp":
        sys.stderr.write(
            "pour-gym: this process ran the fluid on OpenMP threads and is forking; the "
            "child will abort. Install the tbb wheel (pip install tbb), give the fluid one "
            "thread (num_threads=1), or start subprocesses with 'spawn' or 'forkserver'.\n"
        )


os.register_at_fork(before=_warn_before_fork)

from pour_gym.fluid.pbf import PBFConfig, PBFluid, default_threads  # noqa: E402
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf  # noqa: E402

__all__ = [
    "TBB_LIBRARY",
    "PBFConfig",
    "PBFluid",
    "SignedDistanceField",
    "build_sdf",
    "default_threads",
]
