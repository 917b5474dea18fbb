"""Particle fluid: position-based fluids in numba, colliding with posed containers.

The fluid kernel runs on one thread (compiled without any threading layer, so a process may
fork after it) or on several (numba's parallel loops; see
:func:`pour_gym.fluid.pbf.default_threads`), on the ``tbb`` wheel's TBB, which survives
``fork()`` (:mod:`pour_gym.io.numba_threads`). Where numba runs them on GNU OpenMP instead
(no tbb wheel, or the user's choice), a child forked after them runs the one-thread build.
"""

from pour_gym.io.numba_threads import use_wheel_tbb

TBB_LIBRARY = use_wheel_tbb()

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
