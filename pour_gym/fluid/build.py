"""The fluid kernel's builds: its driver compiled twice, on first use.

:func:`pour_gym.fluid.kernel._advance` calls seven passes with parallel loops
(``nb.prange``). It is compiled twice (:func:`builds`): calling the passes compiled
without a threading layer (``"serial"``: a process that ran it may still fork), and
calling their parallel builds (``"parallel"``). Both compute the same numbers bit for bit.
Nothing is compiled, patched or loaded when this module is imported: the first call of
:func:`builds` imports the kernel, loads the ``tbb`` wheel's TBB for numba's threading
layer (:func:`pour_gym.io.numba_threads.use_wheel_tbb`) and creates the dispatchers,
which compile on their first call or load from numba's on-disk cache; helper processes
may have compiled them into that cache already (:mod:`pour_gym.fluid.precompile`).

The kernel takes 58 arguments; :class:`KernelArguments` names them in four groups (the
particles, the fluid's constants, the colliders' motion, scratch space) whose fields, in
order, are the kernel's parameters (``tests/test_fluid.py`` checks).
"""

from __future__ import annotations

import functools
import inspect
import types
from typing import NamedTuple

import numba as nb
import numpy as np

from pour_gym.fluid.sdf import FASTMATH, NO_REFCOUNT, PART_CACHE
from pour_gym.io.numba_threads import twin, use_wheel_tbb

BUILDS = ("serial", "parallel")


def _compile_twice(passes: tuple, driver: types.FunctionType, noalias: dict) -> dict:
    """The driver compiled twice: calling serial passes, and calling parallel builds.

    The serial build runs without numba's runtime (:data:`NO_REFCOUNT`: none of its
    functions allocates); the parallel loops need it for their scheduling. ``noalias``:
    :data:`pour_gym.fluid.kernel.NOALIAS`.
    """
    fast = {"fastmath": FASTMATH, "error_model": "numpy", **noalias}
    part = {"cache": PART_CACHE, **fast}
    serial = dict(driver.__globals__)
    parallel = dict(driver.__globals__)
    for f in passes:
        serial[f.__name__] = nb.njit(**part, **NO_REFCOUNT)(f)
        parallel[f.__name__] = nb.njit(**part, parallel=True)(twin(f, "_parallel", parallel))
    return {
        # nogil: the envs of a vector env step their one-thread fluids in threads of one
        # process (pour_gym.envs.vector).
        False: nb.njit(cache=True, nogil=True, **fast, **NO_REFCOUNT)(
            twin(driver, "_serial", serial)
        ),
        True: nb.njit(cache=True, **fast)(twin(driver, "_parallel", parallel)),
    }


# The kernel: serially (no threading layer is ever loaded, so a process that used it may


@functools.cache
def builds() -> dict:
    """The kernel's two builds by name, ``{"serial": ..., "parallel": ...}`` (numba dispatchers).

    The first call loads the wheel's TBB (before numba starts a threading layer, which it
    does at a parallel build's first call) and imports the kernel.
    """
    use_wheel_tbb()
    import pour_gym.fluid.kernel as kernel

    passes = (
        kernel._pass_predict,
        kernel._pass_neighbours,
        kernel._pass_lambda,
        kernel._pass_correct,
        kernel._pass_collide,
        kernel._pass_viscosity,
        kernel._pass_finish,
    )
    compiled = _compile_twice(passes, kernel._advance, kernel.NOALIAS)
    return {"serial": compiled[False], "parallel": compiled[True]}


@functools.cache
def parameters() -> tuple[str, ...]:
    """The names of the kernel's arguments, in order."""
    import pour_gym.fluid.kernel as kernel

    return tuple(inspect.signature(kernel._advance).parameters)


class ParticleState(NamedTuple):
    """The kernel's particles and the step's length.

    Positions ``x`` (N, 3) m and velocities ``v`` (N, 3) m/s, advanced in place; ``dt`` s.
    """

    x: np.ndarray
    v: np.ndarray
    dt: float


class FluidConstants(NamedTuple):
    """The kernel's constants of one fluid (SI; see :class:`PBFConfig`).

    ``h_max``: the longest substep, s; ``limit``: the CFL bound on a substep's travel, m;
    ``gz``: gravity, m/s^2; ``floor``: the table's height, m (-inf: none);
    ``floor_decay``: the table's friction, 1/s; ``h``: the smoothing radius, m; ``vol``:
    a particle's m / rho_0, m^3; ``eps``, ``scorr``, ``w_dq``: the constraint's
    relaxation, artificial pressure and its reference kernel value; ``iterations``,
    ``tension``, ``omega`` (over-relaxation), ``wall_on`` (wall density) and its
    ``wall_table``, the particle ``radius`` (m) and the ``xsph`` coefficient;
    ``viscosity``: the kinematic viscosity of the implicit viscosity pass, m^2/s (0: none),
    with its Laplacian's scale ``c_lap`` (1/m^2 over the kernel's unscaled weight) and
    the Laplacian's diagonal at rest ``lap_rest``, 1/m^2; ``no_slip``: the walls hold the
    viscous liquid (see :class:`PBFConfig`).
    """

    h_max: float
    limit: float
    gz: float
    floor: float
    floor_decay: float
    h: float
    vol: float
    eps: float
    scorr: float
    w_dq: float
    iterations: int
    tension: float
    omega: float
    wall_on: bool
    wall_table: np.ndarray
    radius: float
    xsph: float
    viscosity: float
    c_lap: float
    lap_rest: float
    no_slip: bool


class ColliderMotion(NamedTuple):
    """The containers' fields and their motion over the step.

    ``fvals``, ``fint``, ``fgeo``: the fields packed (:meth:`PBFluid._fields`); poses from
    rotation ``r0`` (quaternion ``q0``) and translation ``t0`` to ``r1``/``q1``/``t1``,
    one row per collider; ``wall_speed``: the fastest wall's speed, m/s.
    """

    fvals: np.ndarray
    fint: np.ndarray
    fgeo: np.ndarray
    q0: np.ndarray
    q1: np.ndarray
    r0: np.ndarray
    r1: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    wall_speed: float


class Scratch(NamedTuple):
    """The kernel's working arrays, sized to the particles and colliders (contents free).

    ``chunks``: the runs the density, correction and velocity passes split them into.
    """

    p: np.ndarray
    p2: np.ndarray
    prev: np.ndarray
    vn: np.ndarray
    lam: np.ndarray
    wall: np.ndarray
    nbr: np.ndarray
    nbr_count: np.ndarray
    pair_g: np.ndarray
    pair_s: np.ndarray
    keys: np.ndarray
    order: np.ndarray
    start: np.ndarray
    sorted_p: np.ndarray
    grid: np.ndarray
    corrected: np.ndarray
    rot_s: np.ndarray
    tr_s: np.ndarray
    rot_e: np.ndarray
    tr_e: np.ndarray
    chunks: int
    near: np.ndarray
    later: np.ndarray
    n_later: np.ndarray


class KernelArguments(NamedTuple):
    """Everything a step passes to the compiled kernel, by group."""

    particles: ParticleState
    constants: FluidConstants
    colliders: ColliderMotion
    scratch: Scratch

    def flat(self) -> tuple:
        """The arguments in the kernel's order (its parameters are the groups' fields)."""
        return (*self.particles, *self.constants, *self.colliders, *self.scratch)

    @staticmethod
    def names() -> tuple[str, ...]:
        """The groups' field names in the kernel's order."""
        groups = (ParticleState, FluidConstants, ColliderMotion, Scratch)
        return tuple(name for group in groups for name in group._fields)
