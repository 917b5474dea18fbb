"""Particle fluid: position-based fluids in numba, colliding with posed containers.

The numba kernels run on OpenMP threads (the fastest layer here: 2.5x the workqueue
layer at 2k particles). GNU OpenMP does not survive ``fork()``: a process that has run
them and then forks (``AsyncVectorEnv`` with its default context, ``multiprocessing``
with ``fork``) gets children that abort. A warning names the fix when that happens: start
subprocesses with ``spawn`` or ``forkserver``.
"""

import os
import sys


def _warn_before_fork() -> None:
    try:
        import numba

        layer = numba.threading_layer()
    except (ImportError, ValueError):  # no parallel kernel has run yet: forking is safe
        return
    if layer == "omp":
        sys.stderr.write(
            "pour-gym: this process ran the fluid on OpenMP threads and is forking; the "
            "child will abort. Start subprocesses with 'spawn' or 'forkserver', e.g. "
            "AsyncVectorEnv(fns, context='spawn') or SubprocVecEnv(fns, "
            "start_method='forkserver').\n"
        )


os.register_at_fork(before=_warn_before_fork)

from pour_gym.fluid.pbf import PBFConfig, PBFluid  # noqa: E402 - after the fork hook
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf  # noqa: E402

__all__ = ["PBFConfig", "PBFluid", "SignedDistanceField", "build_sdf"]
