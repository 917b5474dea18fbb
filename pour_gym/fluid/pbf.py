"""The position-based fluid: its parameters, its colliders and the object that steps it.

:class:`PBFluid` holds the particles and the containers they collide with (posed
signed-distance fields, :mod:`pour_gym.fluid.colliders`), and advances them by calling
the compiled kernel
(:mod:`pour_gym.fluid.kernel`, the method's description), in one of its two builds
(:mod:`pour_gym.fluid.build`; compiled ahead by helper processes,
:mod:`pour_gym.fluid.precompile`). Importing this module compiles nothing: the kernel is
imported and built when a fluid first needs it.

The kernel runs on one thread (compiled without a threading layer, so a process may fork
after using it) or on several (numba's parallel loops); see :func:`default_threads`.

Units are SI. With the default spacing of 5 mm a particle stands for 0.125 ml of water and
a thesis cup holds 1-3 thousand of them.
"""

from __future__ import annotations

import multiprocessing
import os
import warnings
from dataclasses import asdict, dataclass

import numba as nb
import numpy as np

# As modules, not through the package (whose __init__ imports this module).
import pour_gym.fluid.precompile as precompile
from pour_gym.fluid.build import (
    ColliderMotion,
    FluidConstants,
    KernelArguments,
    ParticleState,
    Scratch,
    builds,
)
from pour_gym.fluid.colliders import Collider, collider_travel, quaternion
from pour_gym.fluid.sdf import SignedDistanceField
from pour_gym.io.numba_threads import FORK_WARNING, threads_usable, usable_cores

GRAVITY = np.array([0.0, 0.0, -9.81])
# Water poured from a table-top cup never moves this fast; a particle that does has diverged.
MAX_SPEED = 20.0  # m/s
# Cells of the neighbour grid, at most (2 MB of cell starts). Cells grow beyond the kernel
# radius only when particles spread over more than about 0.26 m^3 at 5 mm particles.
MAX_CELLS = 262_144


@dataclass(frozen=True)
class PBFConfig:
    """Parameters of the fluid.

    Attributes:
        spacing: rest distance between particles, in m; a particle's volume is spacing^3.
        kernel_ratio: smoothing radius over spacing.
        rest_density: in kg/m^3.
        iterations: constraint iterations per substep.
        substep: largest substep, in s (smaller ones are taken when particles or walls
            move fast).
        relaxation: epsilon of the constraint's denominator, relative to its value at rest.
        scorr_k: artificial-pressure strength, relative to lambda at rest.
        scorr_dq: distance of the artificial pressure's reference, over the smoothing radius.
        xsph: XSPH velocity smoothing (Schechter and Bridson's coefficient, no unit): the
            method's own damping of water; 0 for a liquid given a ``viscosity``.
        viscosity: kinematic viscosity of the implicit viscosity pass, in m^2/s (dynamic
            viscosity over density; :class:`pour_gym.fluid.liquid.Liquid` converts); 0
            for none. Below the method's own (1.7e-3 m^2/s at 5 mm without XSPH,
            ``docs/liquids.md``) it changes little.
        no_slip: with a ``viscosity``, the containers' walls and the table hold the liquid
            (the viscous pass sees the fluid beyond a wall moving with it): a viscous
            liquid sticks to its cup, which is what makes it pour slowly. False: walls
            let it slide, as they always do without a viscosity.
        max_travel: a substep moves no particle and no wall farther than this many
            particle radii (the CFL bound; walls are at least 3 mm thick).
        tension: how far below rest density the constraint still pulls particles together
            (0: pressure only, as a liquid without surface tension).
        over_relaxation: factor on each Jacobi correction; above 1 the pressure of a deep
            column builds up in fewer iterations.
        wall_density: count the density a wall stands in for (the fluid has no particles
            beyond it), so particles do not crowd against walls and the table.
        floor_friction: decay rate of the horizontal velocity of particles on the table,
            in 1/s.
        packing: kernel sum of the settled fluid over that of a cubic lattice at the same
            number density. A lattice relaxes into a disordered packing whose kernel sum is
            about 2 % higher, so with 1 the settled fluid holds 2-3 % more particles per
            litre than the lattice it started from (a column 3 % short, pouring ~3 deg
            late); 1.02 makes a particle stand for ``spacing^3`` of water as it settles
            (column heights within 2 % at 2.5 to 9 cm, tests/test_fluid.py).
    """

    spacing: float = 0.005
    kernel_ratio: float = 2.0
    rest_density: float = 1000.0
    iterations: int = 4
    substep: float = 1.0 / 240.0
    relaxation: float = 0.01
    scorr_k: float = 0.02
    scorr_dq: float = 0.2
    xsph: float = 0.05
    viscosity: float = 0.0
    no_slip: bool = True
    max_travel: float = 2.0
    tension: float = 0.0
    over_relaxation: float = 1.5
    wall_density: bool = True
    floor_friction: float = 20.0
    packing: float = 1.02

    def __post_init__(self) -> None:
        if not (np.isfinite(self.viscosity) and self.viscosity >= 0.0):
            raise ValueError(
                f"viscosity is a kinematic viscosity in m^2/s, 0 or more, not {self.viscosity}"
            )

    @property
    def radius(self) -> float:
        """Collision radius of a particle (half the spacing), in m."""
        return 0.5 * self.spacing

    @property
    def particle_volume(self) -> float:
        """Fluid volume each particle stands for, in m^3."""
        return self.spacing**3

    def to_dict(self) -> dict:
        """The parameters as a JSON-serialisable dict."""
        return asdict(self)


def default_threads() -> int:
    """Threads the fluid uses when not told: one per process where processes share cores.

    One environment per core is how reinforcement learning scales here (SB3's
    ``SubprocVecEnv``, Gymnasium's async vector env, Ray workers and RLlib env runners):
    a process started by ``multiprocessing`` runs its fluid on one thread, and so does a
    process whose ``OMP_NUM_THREADS`` says 1 (Ray sets it for its workers). Otherwise the
    fluid takes the cores this process may run on (its CPU affinity), at most
    ``OMP_NUM_THREADS`` and numba's ``NUMBA_NUM_THREADS``.
    """
    if multiprocessing.parent_process() is not None:
        return 1
    cores = usable_cores()
    limit = os.environ.get("OMP_NUM_THREADS", "")
    if limit.strip().isdigit() and int(limit) > 0:
        cores = min(cores, int(limit))
    return max(1, min(cores, nb.config.NUMBA_NUM_THREADS))


def _poly6(r2, h):
    """The poly6 kernel at squared distances ``r2`` (a number or an array), 1/m^3.

    The kernel's constants are computed in Python from these (the compiled kernel inlines
    the same formula): no compile is spent on them.
    """
    d = np.maximum(h * h - np.asarray(r2, dtype=np.float64), 0.0)
    return 315.0 / (64.0 * np.pi * h**9) * d * d * d


def _spiky_grad_scale(r, h):
    """Magnitude factor g with grad W = g * (x_i - x_j) (negative: points inward)."""
    r = np.asarray(r, dtype=np.float64)
    d = np.where((r < h) & (r >= 1e-12), h - r, 0.0)
    return -45.0 / np.pi / (h * h * h * h * h * h) * d * d / np.maximum(r, 1e-12)


def _lap_weight(r, h):
    """The viscosity Laplacian's unscaled pair weight (the kernel's ``_lap_weight``), 1/m."""
    r = np.asarray(r, dtype=np.float64)
    return np.where(r < h, (h - r) ** 2 / np.maximum(r, 0.1 * h), 0.0)


def laplacian_scale(spacing: float, h: float) -> tuple[float, float]:
    """The viscosity Laplacian's scale and its diagonal on a cubic lattice at rest.

    Brookshaw's form ``L f_i = sum_j c w(r_ij) (f_j - f_i)`` is exact on a quadratic when
    ``c`` makes the lattice sum of ``w(r) z^2`` equal 2 (the Laplacian of ``z^2``); the
    diagonal ``sum_j c w(r_ij)`` sets how many Jacobi sweeps the implicit step takes.

    Args:
        spacing: the lattice's spacing, m.
        h: the smoothing radius, m.

    Returns:
        ``(c, diagonal)``: 1/m (times the weight's 1/m gives 1/m^2) and 1/m^2.
    """
    g = np.arange(-4, 5) * spacing
    lattice = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3)
    r = np.linalg.norm(lattice, axis=1)
    w = np.where(r > 0, _lap_weight(r, h), 0.0)
    c = 2.0 / float(np.sum(w * lattice[:, 2] ** 2))
    return c, c * float(w.sum())


def wall_density_table(h: float, vol: float, samples: int = 64) -> np.ndarray:
    """Relative density a flat wall's half-space would add at distances 0 .. h from it.

    The fluid has no particles inside walls, so a particle near one sees too little
    density; a full half-space of fluid beyond the wall would add ``vol * sum W``, which in
    the continuum limit is the integral of the kernel over that half-space.

    Args:
        h: smoothing radius, m.
        vol: m / rho_0 of a particle, m^3.
        samples: table entries.

    Returns:
        (samples,) density over rest density, for distances ``linspace(0, h, samples)``.
    """
    d = np.linspace(0.0, h, samples)
    # Integrate W over the cap {z > d} of the kernel's ball in slabs of thickness dz.
    z = np.linspace(0.0, h, 400)
    dz = z[1] - z[0]
    slab = np.zeros_like(z)
    for k, zk in enumerate(z):
        rr = np.linspace(0.0, np.sqrt(max(h * h - zk * zk, 0.0)), 200)
        w = 315.0 / (64.0 * np.pi * h**9) * np.clip(h * h - rr * rr - zk * zk, 0.0, None) ** 3
        slab[k] = np.trapezoid(2.0 * np.pi * rr * w, rr)
    cum = np.cumsum(slab[::-1])[::-1] * dz
    # The continuum integral over all space is 1 / vol' for a lattice: scale to its sum.
    total = 2.0 * cum[0]
    return np.interp(d, z, cum) / total


class PBFluid:
    """A position-based fluid colliding with posed containers.

    Args:
        positions: (N, 3) initial particle positions, m.
        config: fluid parameters.
        floor: height of the table (a plane the fluid rests on), m; ``None`` for none.
        max_neighbours: neighbour slots per particle.
        num_threads: threads of the kernel; ``None`` for :func:`default_threads`. With 1
            the kernel is compiled without a threading layer (safe to fork afterwards).

    Attributes:
        corrections: particles put back out of a wall they had tunnelled into during the
            last step (a measure of how hard the last motion was to resolve).
    """

    def __init__(
        self,
        positions: np.ndarray,
        config: PBFConfig | None = None,
        floor: float | None = 0.0,
        max_neighbours: int = 64,
        num_threads: int | None = None,
    ):
        self.config = cfg = config or PBFConfig()
        self.floor = floor
        self.max_neighbours = max_neighbours
        if num_threads is not None and int(num_threads) < 1:
            raise ValueError(f"num_threads must be at least 1 (or None), not {num_threads}")
        self.num_threads = default_threads() if num_threads is None else int(num_threads)
        self._warned_fork = False
        self.x = np.empty((0, 3))
        self.v = np.empty((0, 3))
        # A copy: the fluid moves its particles in place, and the caller's array is theirs.
        self._allocate(np.array(positions, dtype=np.float64).reshape(-1, 3), None)
        if self.count:
            self._compile_soon()
        self.colliders: list[Collider] = []
        self._start = np.zeros(MAX_CELLS + 1, dtype=np.int64)
        # Runs of particles of the constraint and velocity passes: one on one thread, eight
        # per thread on several (fewer are not spread over the threads).
        self._chunks = 1 if self.num_threads == 1 else 8 * self.num_threads
        self._packed_fields: list[SignedDistanceField] | None = None  # what _packed holds
        self._packed: tuple = ()
        self.h = cfg.kernel_ratio * cfg.spacing
        g = np.arange(-4, 5) * cfg.spacing
        lattice = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3)
        # m / rho_0 such that a cubic lattice at the rest spacing is at rest density (times
        # `packing`, for the disordered fluid a lattice settles into): with spacing^3
        # instead, the kernel sum would settle the fluid about 10 % denser than the
        # lattice, and a cup would hold 10 % more than its particle count.
        self._vol = cfg.packing / float(_poly6((lattice * lattice).sum(axis=1), self.h).sum())
        # Scales at rest, from a full lattice neighbourhood: epsilon and s_corr relative
        # to them keep the parameters meaningful in SI units.
        r = np.linalg.norm(lattice, axis=1)
        near = (r > 0) & (r < self.h)
        gs = _spiky_grad_scale(r[near], self.h) * self._vol
        rest_sum = float(np.sum(gs**2 * r[near] ** 2))
        self._eps = cfg.relaxation * rest_sum
        self._scorr = cfg.scorr_k / rest_sum
        self._w_dq = float(_poly6((cfg.scorr_dq * self.h) ** 2, self.h))
        self._wall_table = wall_density_table(self.h, self._vol)
        self._c_lap, self._lap_rest = laplacian_scale(cfg.spacing, self.h)
        # The kernel's constants: all fixed by the config and the construction.
        self._constants = FluidConstants(
            h_max=float(cfg.substep),
            limit=float(cfg.max_travel * cfg.radius),
            gz=float(GRAVITY[2]),
            floor=-np.inf if self.floor is None else float(self.floor),
            floor_decay=float(cfg.floor_friction),
            h=float(self.h),
            vol=float(self._vol),
            eps=float(self._eps),
            scorr=float(self._scorr),
            w_dq=float(self._w_dq),
            iterations=int(cfg.iterations),
            tension=float(cfg.tension),
            omega=float(cfg.over_relaxation),
            wall_on=bool(cfg.wall_density),
            wall_table=self._wall_table,
            radius=float(cfg.radius),
            xsph=float(cfg.xsph),
            viscosity=float(cfg.viscosity),
            c_lap=self._c_lap,
            lap_rest=self._lap_rest,
            no_slip=bool(cfg.no_slip),
        )
        self.time = 0.0
        self.corrections = 0

    def set_viscosity(self, config: PBFConfig) -> None:
        """Take ``config``'s viscosity, XSPH and walls (another liquid's); the rest stays.

        Raises:
            ValueError: ``config`` differs from this fluid's in anything else (a spacing,
                say: the particles would stand for other volumes).
        """
        free = {"viscosity": 0.0, "xsph": 0.0, "no_slip": True}
        mine = {**self.config.to_dict(), **free}
        theirs = {**config.to_dict(), **free}
        if mine != theirs:
            changed = sorted(k for k in mine if mine[k] != theirs[k])
            raise ValueError(f"a liquid changes the viscosity and XSPH only, not {changed}")
        self.config = config
        self._constants = self._constants._replace(
            xsph=float(config.xsph), viscosity=float(config.viscosity), no_slip=config.no_slip
        )

    def _allocate(self, x: np.ndarray, v: np.ndarray | None) -> None:
        """Take new particle arrays and size the scratch buffers to them."""
        n = len(x)
        self.x = np.ascontiguousarray(x, dtype=np.float64)
        self.v = np.zeros_like(self.x) if v is None else np.ascontiguousarray(v, dtype=np.float64)
        self._p = np.empty_like(self.x)
        self._prev = np.empty_like(self.x)
        self._vn = np.empty_like(self.x)
        self._sorted = np.empty_like(self.x)
        self._keys = np.empty(n, dtype=np.int64)
        self._order = np.empty(n, dtype=np.int64)
        # Neighbour lists in 32 bits: they are the kernel's largest arrays.
        self._nbr = np.empty((n, self.max_neighbours), dtype=np.int32)
        self._nbr_count = np.zeros(n, dtype=np.int64)
        # Each particle's later neighbours in the sort (the threaded neighbour search).
        self._later = np.empty((n, self.max_neighbours), dtype=np.int32)
        self._n_later = np.zeros(n, dtype=np.int64)
        self._pair_g = np.empty((n, self.max_neighbours), dtype=np.float32)
        self._pair_s = np.empty((n, self.max_neighbours), dtype=np.float32)
        self._lam = np.zeros(n)
        self._p2 = np.empty_like(self.x)
        self._wall = np.zeros((n, 4))
        self._corrected = np.zeros(n, dtype=np.int64)

    @property
    def count(self) -> int:
        """Number of particles."""
        return len(self.x)

    def add(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Add particles; returns their indices (they are appended at the end).

        Args:
            positions: (K, 3) positions, m.
            velocities: (K, 3) velocities, m/s (zero if not given).
        """
        p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        v = np.zeros_like(p) if velocities is None else np.asarray(velocities, float).reshape(-1, 3)
        if not (np.isfinite(p).all() and np.isfinite(v).all()):
            raise ValueError("particle positions and velocities must be finite")
        n = self.count
        self._allocate(np.concatenate([self.x, p]), np.concatenate([self.v, v]))
        self._compile_soon()
        return np.arange(n, n + len(p))

    def remove(self, mask: np.ndarray) -> None:
        """Remove the particles where ``mask`` is true; the others keep their order."""
        keep = ~np.asarray(mask, dtype=bool)
        if keep.shape != (self.count,):
            raise ValueError(f"mask of shape {keep.shape} for {self.count} particles")
        self._allocate(self.x[keep], self.v[keep])

    def relative_density(self) -> np.ndarray:
        """SPH density of each particle over the rest density (1 at rest, in the bulk)."""
        from scipy.spatial import cKDTree

        tree = cKDTree(self.x)
        pairs = tree.sparse_distance_matrix(tree, self.h, output_type="coo_matrix")
        # The pairs include each particle with itself (distance 0), its own contribution.
        w = _poly6(pairs.data * pairs.data, self.h)
        return np.bincount(pairs.row, w, minlength=len(self.x)) * self._vol

    def add_collider(self, sdf: SignedDistanceField, rotation=None, translation=None) -> Collider:
        """Add a container's field at a pose; returns the collider, whose pose can be set."""
        c = Collider.placed(rotation, translation, sdf=sdf)
        self.colliders.append(c)
        return c

    def _fields(self) -> tuple:
        """The colliders' fields for the kernel (packed once per set of colliders).

        Returns:
            ``(fvals, fint, fgeo)``: every field's values as one float32 run, (offset, nx,
            ny, nz) per field, and (origin x, y, z, spacing, box top x, y, z, smallest value
            on the box's faces) per field.
        """
        fields = [c.sdf for c in self.colliders]
        # By identity, against the fields themselves (kept): an id alone could be reused by
        # a new field once the one it named was freed.
        packed = self._packed_fields
        if (
            packed is None
            or len(packed) != len(fields)
            or any(a is not b for a, b in zip(fields, packed, strict=True))
        ):
            sizes = [f.values.size for f in fields]
            offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]) if fields else []
            self._packed = (
                np.concatenate([f.flat for f in fields]) if fields else np.zeros(1, np.float32),
                np.array([[o, *f.values.shape] for o, f in zip(offsets, fields, strict=True)],
                         dtype=np.int64).reshape(-1, 4),
                np.array([[*f.origin, f.spacing, *f.upper, f.edge_min] for f in fields],
                         dtype=np.float64).reshape(-1, 8),
            )  # fmt: skip
            self._packed_fields = fields
        return self._packed

    def _compile_soon(self) -> None:
        """Start compiling the kernel in helpers (if not cached): this fluid will step."""
        precompile.start(parallel=self._threaded())

    def _threaded(self) -> bool:
        """Whether this fluid runs the threaded build once it is compiled.

        Not in a child forked from a process whose parallel loops ran on GNU OpenMP, which
        would be killed at its first parallel loop (:mod:`pour_gym.io.numba_threads`): the
        one-thread build runs, the same numbers, after a warning.
        """
        if self.num_threads == 1:
            return False
        if threads_usable():
            return True
        if not self._warned_fork:
            self._warned_fork = True
            what = f"the fluid (num_threads={self.num_threads})"
            warnings.warn(FORK_WARNING.format(what=what), RuntimeWarning, stacklevel=3)
        return False

    @property
    def build(self) -> str:
        """The kernel build the next step runs: ``"serial"`` or ``"parallel"``.

        A fluid on several threads runs the serial build (the same numbers) until a helper
        process has compiled the parallel one (:mod:`pour_gym.fluid.precompile`).
        """
        if self._threaded() and precompile.ready("parallel", wait=False):
            return "parallel"
        return "serial"

    def wait_for_kernel(self) -> None:
        """Wait until the build this fluid wants is compiled (before timing it, say)."""
        precompile.ready("parallel" if self._threaded() else "serial", wait=True)

    def kernel_arguments(self, dt: float) -> KernelArguments:
        """The compiled kernel's arguments for a step of ``dt`` s, in named groups.

        The colliders' previous poses are set where they have none yet.
        """
        for c in self.colliders:
            if c.prev_rotation is None:
                c.prev_rotation, c.prev_translation = c.rotation.copy(), c.translation.copy()
        k = len(self.colliders)
        fvals, fint, fgeo = self._fields()
        r0 = np.array([c.prev_rotation for c in self.colliders], dtype=np.float64).reshape(k, 3, 3)
        r1 = np.array([c.rotation for c in self.colliders], dtype=np.float64).reshape(k, 3, 3)
        t0 = np.array([c.prev_translation for c in self.colliders], dtype=np.float64)
        t1 = np.array([c.translation for c in self.colliders], dtype=np.float64)
        q0 = np.empty((k, 4))
        q1 = np.empty((k, 4))
        for j, c in enumerate(self.colliders):
            # The last step's end quaternion if it is still the start's (a teleport sets
            # the previous pose anew), and a new one only for a turned container.
            known = c.prev_quaternion
            same = known is not None and np.array_equal(known[0], r0[j])
            q0[j] = known[1] if same else quaternion(r0[j])
            q1[j] = q0[j] if np.array_equal(r0[j], r1[j]) else quaternion(r1[j])
        wall_speed = max((collider_travel(c, c.sdf) for c in self.colliders), default=0.0) / dt
        return KernelArguments(
            particles=ParticleState(x=self.x, v=self.v, dt=float(dt)),
            constants=self._constants,
            colliders=ColliderMotion(
                fvals=fvals,
                fint=fint,
                fgeo=fgeo,
                q0=q0,
                q1=q1,
                r0=np.ascontiguousarray(r0),
                r1=np.ascontiguousarray(r1),
                t0=t0.reshape(k, 3),
                t1=t1.reshape(k, 3),
                wall_speed=float(wall_speed),
            ),
            scratch=Scratch(
                p=self._p,
                p2=self._p2,
                prev=self._prev,
                vn=self._vn,
                lam=self._lam,
                wall=self._wall,
                nbr=self._nbr,
                nbr_count=self._nbr_count,
                pair_g=self._pair_g,
                pair_s=self._pair_s,
                keys=self._keys,
                order=self._order,
                start=self._start,
                sorted_p=self._sorted,
                grid=np.empty(7),
                corrected=self._corrected,
                rot_s=np.empty((k, 3, 3)),
                tr_s=np.empty((k, 3)),
                rot_e=np.empty((k, 3, 3)),
                tr_e=np.empty((k, 3)),
                chunks=self._chunks,
                near=np.empty((self.count, k)),
                later=self._later,
                n_later=self._n_later,
            ),
        )

    def step(self, dt: float) -> int:
        """Advance by ``dt`` seconds; returns the number of substeps taken.

        Colliders move from their previous pose (at the last call) to their current one
        over the step, linearly in position and by slerp in rotation.

        Raises:
            FloatingPointError: a particle moves faster than any water here, or a position
                became NaN or infinite.
        """
        if dt <= 0.0:
            raise ValueError(f"a step takes a positive time, not {dt} s")
        speed = float(np.sqrt((self.v**2).sum(axis=1).max())) if len(self.v) else 0.0
        if not np.isfinite(speed) or speed > MAX_SPEED:
            raise FloatingPointError(
                f"the fluid diverged: a particle moves at {speed:.3g} m/s (limit {MAX_SPEED})"
            )
        args = self.kernel_arguments(dt)
        n_sub = 0
        self._corrected[:] = 0
        if self.count:
            # On one thread the serial build: it never loads a threading layer (a process
            # may fork safely after it), and a parallel build on one thread would wait on
            # the threading layer at every loop (ten times slower with TBB). On several, the
            # serial build serves (the same numbers) until a helper has compiled the other.
            parallel = self.build == "parallel"
            if parallel:
                nb.set_num_threads(min(self.num_threads, nb.config.NUMBA_NUM_THREADS))
            else:
                precompile.ready("serial", wait=True)
            n_sub = builds()["parallel" if parallel else "serial"](*args.flat())
        q1 = args.colliders.q1
        for j, c in enumerate(self.colliders):
            c.prev_rotation, c.prev_translation = c.rotation.copy(), c.translation.copy()
            c.prev_quaternion = (c.prev_rotation, q1[j].copy())
        if not np.isfinite(self.x).all():
            raise FloatingPointError("the fluid diverged: a particle position is NaN or infinite")
        self.corrections = int(self._corrected.sum())
        self.time += dt
        return n_sub
