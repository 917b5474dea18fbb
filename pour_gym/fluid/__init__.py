"""Particle fluid: position-based fluids in numba, colliding with posed containers.

Three parts: the compiled kernel's source (:mod:`~pour_gym.fluid.kernel`), its builds
(:mod:`~pour_gym.fluid.build`, compiled ahead by helper processes:
:mod:`~pour_gym.fluid.precompile`), and the fluid object with its colliders
(:mod:`~pour_gym.fluid.pbf`). Importing the package compiles nothing and loads no
threading library: the kernel is built when a fluid first needs it.

The fluid kernel runs on one thread (compiled without any threading layer, so a process may
fork after it) or on several (numba's parallel loops; see
:func:`pour_gym.fluid.pbf.default_threads`), on the ``tbb`` wheel's TBB (loaded when the
kernel is built), which survives ``fork()`` (:mod:`pour_gym.io.numba_threads`). Where
numba runs them on GNU OpenMP instead (no tbb wheel, or the user's choice), a child forked
after them runs the one-thread build.
``POUR_GYM_CPU`` pins the processor the kernel is compiled for
(:mod:`pour_gym.fluid.target`), for episodes that agree across machines.
"""

from pour_gym.fluid.target import pinned_target

# POUR_GYM_CPU: the processor numba compiles for, set before anything is compiled.
CPU_TARGET = pinned_target()

from pour_gym.fluid.pbf import PBFConfig, PBFluid, default_threads  # noqa: E402
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf  # noqa: E402

__all__ = [
    "CPU_TARGET",
    "PBFConfig",
    "PBFluid",
    "SignedDistanceField",
    "build_sdf",
    "default_threads",
]
