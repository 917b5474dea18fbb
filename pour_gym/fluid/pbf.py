"""Position-based fluids (Macklin and Mueller 2013), compiled with numba.

Each substep: apply gravity and predict positions; find neighbours with a hashed cell list
(arrays allocated once, refilled in place); iterate the density constraint
``C_i = rho_i / rho_0 - 1`` (clamped to compression, so that a free surface has no
artificial cohesion), with the paper's artificial pressure ``s_corr`` against clumping;
project out of the containers' walls through their signed-distance fields, posed by the
containers' current transforms; update velocities from the displacement, and smooth them
with XSPH viscosity.

Units are SI. With the default spacing of 5 mm a particle stands for 0.125 ml of water and
a thesis cup holds 1-3 thousand of them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numba as nb
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from pour_gym.fluid.sdf import SignedDistanceField, sample_sdf

GRAVITY = np.array([0.0, 0.0, -9.81])
# Particles per parallel work item in loops that need scratch vectors.
CHUNK = 64
# Cells of the neighbour grid, at most (about 16 MB of cell starts).
MAX_CELLS = 2_000_000
# Water poured from a table-top cup never moves this fast; a particle that does has diverged.
MAX_SPEED = 20.0  # m/s


@dataclass(frozen=True)
class PBFConfig:
    """Parameters of the fluid.

    Attributes:
        spacing: rest distance between particles, in m; a particle's volume is spacing^3.
        kernel_ratio: smoothing radius over spacing.
        rest_density: in kg/m^3.
        iterations: constraint iterations per substep.
        substep: largest substep, in s (smaller ones are taken when particles move fast).
        relaxation: epsilon of the constraint's denominator, relative to its value at rest.
        scorr_k: artificial-pressure strength, relative to lambda at rest.
        scorr_dq: distance of the artificial pressure's reference, over the smoothing radius.
        xsph: XSPH viscosity coefficient.
        max_travel: a substep moves no particle farther than this many particle radii.
        tension: how far below rest density the constraint still pulls particles together
            (0: pressure only, as a liquid without surface tension).
        over_relaxation: factor on each Jacobi correction; above 1 the pressure of a deep
            column builds up in fewer iterations.
        wall_density: count the density a wall stands in for (the fluid has no particles
            beyond it), so particles do not crowd against walls and the table.
        floor_friction: decay rate of the horizontal velocity of particles on the table,
            in 1/s.
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
    max_travel: float = 1.5
    tension: float = 0.0
    over_relaxation: float = 1.5
    wall_density: bool = True
    floor_friction: float = 20.0

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


@nb.njit(cache=True, inline="always")
def _poly6(r2, h):
    if r2 >= h * h:
        return 0.0
    d = h * h - r2
    return 315.0 / (64.0 * np.pi * h**9) * d * d * d


@nb.njit(cache=True, inline="always")
def _spiky_grad_scale(r, h):
    """Magnitude factor g with grad W = g * (x_i - x_j) (negative: points inward)."""
    if r >= h or r < 1e-12:
        return 0.0
    d = h - r
    return -45.0 / np.pi / (h * h * h * h * h * h) * d * d / r


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


@nb.njit(cache=True)
def _sort_cells(p, lo, cell, dims, table, order, start, sorted_p):
    """Counting sort of the particles by their cell in a dense grid over their bounds.

    Cells are numbered z fastest, so the three cells of a column ``(cx, cy, cz-1..cz+1)``
    are one contiguous run of the sorted arrays. ``sorted_p`` receives the positions in
    cell order, so that the neighbour search reads contiguous memory.
    """
    n = p.shape[0]
    ny, nz = dims[1], dims[2]
    n_cells = dims[0] * ny * nz
    start[: n_cells + 1] = 0
    for i in range(n):
        cx = int((p[i, 0] - lo[0]) / cell)
        cy = int((p[i, 1] - lo[1]) / cell)
        cz = int((p[i, 2] - lo[2]) / cell)
        k = (cx * ny + cy) * nz + cz
        table[i] = k
        start[k + 1] += 1
    for k in range(n_cells):
        start[k + 1] += start[k]
    for i in range(n):
        k = table[i]
        s = start[k]
        order[s] = i
        sorted_p[s, 0] = p[i, 0]
        sorted_p[s, 1] = p[i, 1]
        sorted_p[s, 2] = p[i, 2]
        start[k] = s + 1
    # Undo the shift the fill loop made: start[k] is again the first slot of cell k.
    for k in range(n_cells, 0, -1):
        start[k] = start[k - 1]
    start[0] = 0


@nb.njit(parallel=True, cache=True, fastmath=True)
def _find_neighbours(p, sorted_p, h, lo, cell, dims, order, start, nbr, nbr_count):
    """Each particle's neighbours within h (<= the cell size), from the sorted cells."""
    n = p.shape[0]
    nx, ny, nz = dims[0], dims[1], dims[2]
    max_nbr = nbr.shape[1]
    h2 = h * h
    for i in nb.prange(n):
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        cx = int((px - lo[0]) / cell)
        cy = int((py - lo[1]) / cell)
        cz = int((pz - lo[2]) / cell)
        z0 = max(cz - 1, 0)
        z1 = min(cz + 1, nz - 1)
        c = 0
        for ax in range(max(cx - 1, 0), min(cx + 2, nx)):
            for ay in range(max(cy - 1, 0), min(cy + 2, ny)):
                base = (ax * ny + ay) * nz
                for s in range(start[base + z0], start[base + z1 + 1]):
                    rx = px - sorted_p[s, 0]
                    ry = py - sorted_p[s, 1]
                    rz = pz - sorted_p[s, 2]
                    if rx * rx + ry * ry + rz * rz < h2 and c < max_nbr:
                        j = order[s]
                        if j != i:
                            nbr[i, c] = j
                            c += 1
        nbr_count[i] = c


@nb.njit(parallel=True, cache=True, fastmath=True)
def _solve_density(
    p,
    nbr,
    nbr_count,
    lam,
    delta,
    h,
    vol,
    eps,
    scorr_k,
    w_dq,
    iterations,
    tension,
    omega,
    wall,
    wall_table,
):
    """Jacobi iterations of the clamped density constraint with artificial pressure.

    ``wall[i]`` is particle i's distance to the nearest wall; ``wall_table`` the density a
    wall adds at distances 0 .. h (see :func:`wall_density_table`).
    """
    n_table = wall_table.shape[0]
    n = p.shape[0]
    h2 = h * h
    # Kernel constants, with the particle volume m / rho_0 folded in.
    c_poly = 315.0 / (64.0 * np.pi * h**9) * vol
    c_spiky = -45.0 / (np.pi * h**6) * vol
    w_dq = w_dq * vol
    w0 = c_poly * h2 * h2 * h2
    for _ in range(iterations):
        for i in nb.prange(n):
            rho = w0
            gx = 0.0
            gy = 0.0
            gz = 0.0
            sum2 = 0.0
            for q in range(nbr_count[i]):
                j = nbr[i, q]
                rx = p[i, 0] - p[j, 0]
                ry = p[i, 1] - p[j, 1]
                rz = p[i, 2] - p[j, 2]
                r2 = rx * rx + ry * ry + rz * rz
                if r2 >= h2:
                    continue
                d2 = h2 - r2
                rho += c_poly * d2 * d2 * d2
                r = np.sqrt(r2)
                g = c_spiky * (h - r) * (h - r) / max(r, 1e-12)
                gx += g * rx
                gy += g * ry
                gz += g * rz
                sum2 += g * g * r2
            if wall[i] < h:
                u = max(wall[i], 0.0) / h * (n_table - 1)
                k = min(int(u), n_table - 2)
                f = u - k
                rho += wall_table[k] * (1.0 - f) + wall_table[k + 1] * f
            c = rho - 1.0
            if c < -tension:
                c = -tension  # limited tension: a free surface is not pulled together
            lam[i] = -c / (sum2 + gx * gx + gy * gy + gz * gz + eps)
        for i in nb.prange(n):
            dx = 0.0
            dy = 0.0
            dz = 0.0
            for q in range(nbr_count[i]):
                j = nbr[i, q]
                rx = p[i, 0] - p[j, 0]
                ry = p[i, 1] - p[j, 1]
                rz = p[i, 2] - p[j, 2]
                r2 = rx * rx + ry * ry + rz * rz
                if r2 >= h2:
                    continue
                d2 = h2 - r2
                ratio = c_poly * d2 * d2 * d2 / w_dq
                ratio2 = ratio * ratio
                s = -scorr_k * ratio2 * ratio2
                r = np.sqrt(r2)
                g = c_spiky * (h - r) * (h - r) / max(r, 1e-12) * (lam[i] + lam[j] + s)
                dx += g * rx
                dy += g * ry
                dz += g * rz
            delta[i, 0] = dx
            delta[i, 1] = dy
            delta[i, 2] = dz
        for i in nb.prange(n):
            p[i, 0] += omega * delta[i, 0]
            p[i, 1] += omega * delta[i, 1]
            p[i, 2] += omega * delta[i, 2]


@nb.njit(parallel=True, cache=True, fastmath=True)
def _limit_travel(p, x_prev, limit):
    """Shorten every displacement of the substep to at most ``limit`` (a CFL bound).

    The substep count is chosen from the speeds at the start of a step; pressure can still
    accelerate a particle within the step, and a particle that crossed more than a wall's
    thickness in one substep could pass through it unseen.
    """
    for i in nb.prange(p.shape[0]):
        dx = p[i, 0] - x_prev[i, 0]
        dy = p[i, 1] - x_prev[i, 1]
        dz = p[i, 2] - x_prev[i, 2]
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d > limit:
            f = limit / d
            p[i, 0] = x_prev[i, 0] + f * dx
            p[i, 1] = x_prev[i, 1] + f * dy
            p[i, 2] = x_prev[i, 2] + f * dz


@nb.njit(parallel=True, cache=True, fastmath=True)
def _collide(p, x_prev, radius, values, origin, spacing, rot, trans, prev_rot, prev_trans):
    """Push particles out of one container's material, in the container's frame.

    The particle's start-of-substep position is taken into the container's previous pose,
    its end into the current one: if the straight path between them crosses the middle of
    the wall (the distance changes sign along it) the particle is put back on the side it
    came from, so a fast particle cannot tunnel through a thin wall. The push along the
    field's gradient is repeated, because one push out of a corner can land near the other
    wall of the corner.
    """
    n = p.shape[0]
    # Scratch vectors per chunk of particles: an allocation per particle costs as much as
    # the collision test itself.
    for chunk in nb.prange((n + CHUNK - 1) // CHUNK):
        q = np.empty(3)
        q0 = np.empty(3)
        qm = np.empty(3)
        grad = np.empty(3)
        for i in range(chunk * CHUNK, min(n, (chunk + 1) * CHUNK)):
            _collide_one(
                p,
                x_prev,
                i,
                radius,
                values,
                origin,
                spacing,
                rot,
                trans,
                prev_rot,
                prev_trans,
                q,
                q0,
                qm,
                grad,
            )


@nb.njit(cache=True, fastmath=True)
def _collide_one(
    p, x_prev, i, radius, values, origin, spacing, rot, trans, prev_rot, prev_trans, q, q0, qm, grad
):
    """:func:`_collide` for particle i, with scratch vectors q, q0, qm, grad."""
    for a in range(3):
        q[a] = (
            rot[0, a] * (p[i, 0] - trans[0])
            + rot[1, a] * (p[i, 1] - trans[1])
            + rot[2, a] * (p[i, 2] - trans[2])
        )
        q0[a] = (
            prev_rot[0, a] * (x_prev[i, 0] - prev_trans[0])
            + prev_rot[1, a] * (x_prev[i, 1] - prev_trans[1])
            + prev_rot[2, a] * (x_prev[i, 2] - prev_trans[2])
        )
    d = sample_sdf(values, origin, spacing, q, grad)
    if d >= radius:
        return
    d0 = sample_sdf(values, origin, spacing, q0, qm)
    if d0 > 0.0 and d < -0.25 * radius:
        # Crossed into the wall from outside: march back along the path to the surface.
        lo, hi = 0.0, 1.0
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            for a in range(3):
                qm[a] = q0[a] + mid * (q[a] - q0[a])
            if sample_sdf(values, origin, spacing, qm, grad) > radius:
                lo = mid
            else:
                hi = mid
        for a in range(3):
            q[a] = q0[a] + lo * (q[a] - q0[a])
        d = sample_sdf(values, origin, spacing, q, grad)
    for _ in range(3):
        if d >= radius:
            break
        push = radius - d
        for a in range(3):
            q[a] += push * grad[a]
        d = sample_sdf(values, origin, spacing, q, grad)
    for a in range(3):
        p[i, a] = rot[a, 0] * q[0] + rot[a, 1] * q[1] + rot[a, 2] * q[2] + trans[a]


@nb.njit(parallel=True, cache=True, fastmath=True)
def _finish(x, v, vn, p, nbr, nbr_count, h, dt, xsph):
    """Velocities from the displacement, XSPH-smoothed; positions take the prediction.

    ``vn`` is scratch space of the shape of ``v``.
    """
    n = x.shape[0]
    for i in nb.prange(n):
        for a in range(3):
            vn[i, a] = (p[i, a] - x[i, a]) / dt
    w0 = _poly6(0.0, h)
    for i in nb.prange(n):
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for q in range(nbr_count[i]):
            j = nbr[i, q]
            rx = p[i, 0] - p[j, 0]
            ry = p[i, 1] - p[j, 1]
            rz = p[i, 2] - p[j, 2]
            w = _poly6(rx * rx + ry * ry + rz * rz, h) / w0
            sx += (vn[j, 0] - vn[i, 0]) * w
            sy += (vn[j, 1] - vn[i, 1]) * w
            sz += (vn[j, 2] - vn[i, 2]) * w
        v[i, 0] = vn[i, 0] + xsph * sx
        v[i, 1] = vn[i, 1] + xsph * sy
        v[i, 2] = vn[i, 2] + xsph * sz
    for i in nb.prange(n):
        for a in range(3):
            x[i, a] = p[i, a]


@nb.njit(parallel=True, cache=True, fastmath=True)
def _predict(x, v, p, prev, gz, dt):
    """Gravity on the velocities, then predicted positions; keeps the start positions."""
    for i in nb.prange(x.shape[0]):
        v[i, 2] += gz * dt
        for a in range(3):
            prev[i, a] = x[i, a]
            p[i, a] = x[i, a] + v[i, a] * dt


@nb.njit(parallel=True, cache=True, fastmath=True)
def _wall_distance(p, out, values, origin, spacing, rot, trans):
    """out[i] = min(out[i], signed distance of particle i to one container's material)."""
    n = p.shape[0]
    for chunk in nb.prange((n + CHUNK - 1) // CHUNK):
        q = np.empty(3)
        grad = np.empty(3)
        for i in range(chunk * CHUNK, min(n, (chunk + 1) * CHUNK)):
            for a in range(3):
                q[a] = (
                    rot[0, a] * (p[i, 0] - trans[0])
                    + rot[1, a] * (p[i, 1] - trans[1])
                    + rot[2, a] * (p[i, 2] - trans[2])
                )
            d = sample_sdf(values, origin, spacing, q, grad)
            if d < out[i]:
                out[i] = d


def wall_distance(
    points: np.ndarray, sdf: SignedDistanceField, rotation: np.ndarray, translation: np.ndarray
) -> np.ndarray:
    """Signed distance (N,) of world points to a posed container's material, m."""
    out = np.full(len(points), np.inf)
    _wall_distance(
        np.ascontiguousarray(points, dtype=np.float64),
        out,
        sdf.values,
        sdf.origin,
        sdf.spacing,
        np.ascontiguousarray(rotation, dtype=np.float64),
        np.ascontiguousarray(translation, dtype=np.float64),
    )
    return out


# eq=False: colliders are compared by identity; two may be equal in every field.
@dataclass(eq=False, kw_only=True)
class PosedCollider:
    """A container a fluid collides with, at its pose (world = R q + t).

    ``prev_*`` is the pose at the end of the last step; the fluid moves the container from
    there to ``rotation``, ``translation`` over the next step.
    """

    rotation: np.ndarray
    translation: np.ndarray
    prev_rotation: np.ndarray | None = None
    prev_translation: np.ndarray | None = None

    @classmethod
    def placed(cls, rotation=None, translation=None, **handle):
        """A collider at a pose (identity and origin when not given)."""
        return cls(
            rotation=np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64),
            translation=np.zeros(3)
            if translation is None
            else np.asarray(translation, dtype=np.float64),
            **handle,
        )


@dataclass(eq=False, kw_only=True)
class Collider(PosedCollider):
    """A container the PBF fluid collides with through its signed-distance field."""

    sdf: SignedDistanceField


class PBFluid:
    """A position-based fluid colliding with posed containers.

    Args:
        positions: (N, 3) initial particle positions, m.
        config: fluid parameters.
        floor: height of the table (a plane the fluid rests on), m; ``None`` for none.
        max_neighbours: neighbour slots per particle.
    """

    def __init__(
        self,
        positions: np.ndarray,
        config: PBFConfig | None = None,
        floor: float | None = 0.0,
        max_neighbours: int = 64,
    ):
        self.config = cfg = config or PBFConfig()
        self.floor = floor
        self.max_neighbours = max_neighbours
        self.x = np.empty((0, 3))
        self.v = np.empty((0, 3))
        self._allocate(np.ascontiguousarray(positions, dtype=np.float64).reshape(-1, 3), None)
        self._start = np.zeros(1, dtype=np.int64)
        self.colliders: list[Collider] = []
        self.h = cfg.kernel_ratio * cfg.spacing
        g = np.arange(-4, 5) * cfg.spacing
        lattice = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3)
        # m / rho_0 such that a cubic lattice at the rest spacing is exactly at rest
        # density: with spacing^3 instead, the kernel sum would settle the fluid about 10 %
        # denser than the lattice, and a cup would hold 10 % more than its particle count.
        self._vol = 1.0 / sum(_poly6(float(x @ x), self.h) for x in lattice)
        # Scales at rest, from a full lattice neighbourhood: epsilon and s_corr relative
        # to them keep the parameters meaningful in SI units.
        r = np.linalg.norm(lattice, axis=1)
        near = (r > 0) & (r < self.h)
        gs = np.array([_spiky_grad_scale(x, self.h) for x in r[near]]) * self._vol
        rest_sum = float(np.sum(gs**2 * r[near] ** 2))
        self._eps = cfg.relaxation * rest_sum
        self._scorr = cfg.scorr_k / rest_sum
        self._w_dq = _poly6((cfg.scorr_dq * self.h) ** 2, self.h)
        self._wall_table = wall_density_table(self.h, self._vol)
        self.time = 0.0

    def _allocate(self, x: np.ndarray, v: np.ndarray | None) -> None:
        """Take new particle arrays and size the scratch buffers to them."""
        n = len(x)
        self.x = np.ascontiguousarray(x, dtype=np.float64)
        self.v = np.zeros_like(self.x) if v is None else np.ascontiguousarray(v, dtype=np.float64)
        self._p = np.empty_like(self.x)
        self._prev = np.empty_like(self.x)
        self._vn = np.empty_like(self.x)
        self._sorted = np.empty_like(self.x)
        self._table = np.empty(n, dtype=np.int64)
        self._order = np.empty(n, dtype=np.int64)
        self._nbr = np.empty((n, self.max_neighbours), dtype=np.int64)
        self._nbr_count = np.zeros(n, dtype=np.int64)
        self._lam = np.zeros(n)
        self._delta = np.zeros((n, 3))
        self._wall = np.full(n, np.inf)

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
        return np.arange(n, n + len(p))

    def remove(self, mask: np.ndarray) -> None:
        """Remove the particles where ``mask`` is true; the others keep their order."""
        keep = ~np.asarray(mask, dtype=bool)
        if keep.shape != (self.count,):
            raise ValueError(f"mask of shape {keep.shape} for {self.count} particles")
        self._allocate(self.x[keep], self.v[keep])

    def _grid(self, p: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        """A dense cell grid over the particles' bounds (cells of at least h)."""
        lo = p.min(axis=0) - 1e-9
        extent = p.max(axis=0) - lo + 1e-9
        # Particles spread over a table still fit a few million cells; beyond that the
        # cells grow (the search stays exact, it only checks more pairs).
        cell = max(self.h, float(np.cbrt(np.prod(extent + self.h) / MAX_CELLS)))
        dims = (extent // cell).astype(np.int64) + 1
        n_cells = int(np.prod(dims))
        if len(self._start) < n_cells + 1:
            self._start = np.zeros(max(n_cells + 1, 2 * len(self._start)), dtype=np.int64)
        return lo, cell, dims

    def relative_density(self) -> np.ndarray:
        """SPH density of each particle over the rest density (1 at rest, in the bulk)."""
        from scipy.spatial import cKDTree

        tree = cKDTree(self.x)
        pairs = tree.sparse_distance_matrix(tree, self.h, output_type="coo_matrix")
        # The pairs include each particle with itself (distance 0), its own contribution.
        w = np.array([_poly6(r * r, self.h) for r in pairs.data])
        return np.bincount(pairs.row, w, minlength=len(self.x)) * self._vol

    def add_collider(self, sdf: SignedDistanceField, rotation=None, translation=None) -> Collider:
        """Add a container's field at a pose; returns the collider, whose pose can be set."""
        c = Collider.placed(rotation, translation, sdf=sdf)
        self.colliders.append(c)
        return c

    def step(self, dt: float) -> int:
        """Advance by ``dt`` seconds; returns the number of substeps taken.

        Colliders move linearly in position and rotation from their previous pose (at the
        last call) to their current one over the step.

        Raises:
            FloatingPointError: a particle position became NaN or infinite.
        """
        if dt <= 0.0:
            raise ValueError(f"a step takes a positive time, not {dt} s")
        cfg = self.config
        speed = float(np.sqrt((self.v**2).sum(axis=1).max())) if len(self.v) else 0.0
        if not np.isfinite(speed) or speed > MAX_SPEED:
            raise FloatingPointError(
                f"the fluid diverged: a particle moves at {speed:.3g} m/s (limit {MAX_SPEED})"
            )
        limit = cfg.max_travel * cfg.radius
        for c in self.colliders:
            if c.prev_rotation is None:
                c.prev_rotation, c.prev_translation = c.rotation.copy(), c.translation.copy()
        # A wall moves no farther than a particle may in one substep, either.
        wall = max((_collider_travel(c) for c in self.colliders), default=0.0)
        n_sub = max(int(np.ceil(dt / cfg.substep)), int(np.ceil(max(speed * dt, wall) / limit)), 1)
        h_sub = dt / n_sub
        # Each collider's pose at the n_sub + 1 substep boundaries, computed once a step.
        poses = [substep_poses(c, n_sub) for c in self.colliders]
        for s in range(n_sub if self.count else 0):
            _predict(self.x, self.v, self._p, self._prev, GRAVITY[2], h_sub)
            self._wall.fill(np.inf)
            if cfg.wall_density:
                if self.floor is not None:
                    np.subtract(self._p[:, 2], self.floor, out=self._wall)
                for c, (rot, trans) in zip(self.colliders, poses, strict=True):
                    _wall_distance(
                        self._p,
                        self._wall,
                        c.sdf.values,
                        c.sdf.origin,
                        c.sdf.spacing,
                        rot[s + 1],
                        trans[s + 1],
                    )
            lo, cell, dims = self._grid(self._p)
            _sort_cells(
                self._p, lo, cell, dims, self._table, self._order, self._start, self._sorted
            )
            _find_neighbours(
                self._p,
                self._sorted,
                self.h,
                lo,
                cell,
                dims,
                self._order,
                self._start,
                self._nbr,
                self._nbr_count,
            )
            _solve_density(
                self._p,
                self._nbr,
                self._nbr_count,
                self._lam,
                self._delta,
                self.h,
                self._vol,
                self._eps,
                self._scorr,
                self._w_dq,
                cfg.iterations,
                cfg.tension,
                cfg.over_relaxation,
                self._wall,
                self._wall_table,
            )
            _limit_travel(self._p, self._prev, limit)
            for c, (rot, trans) in zip(self.colliders, poses, strict=True):
                _collide(
                    self._p,
                    self._prev,
                    cfg.radius,
                    c.sdf.values,
                    c.sdf.origin,
                    c.sdf.spacing,
                    rot[s + 1],
                    trans[s + 1],
                    rot[s],
                    trans[s],
                )
            if self.floor is not None:
                column = self._p[:, 2]
                np.maximum(column, self.floor + cfg.radius, out=column)
            _finish(
                self.x,
                self.v,
                self._vn,
                self._p,
                self._nbr,
                self._nbr_count,
                self.h,
                h_sub,
                cfg.xsph,
            )
            if self.floor is not None and cfg.floor_friction > 0.0:
                # Water on a table comes to rest instead of gliding away forever.
                on = self.x[:, 2] < self.floor + cfg.radius + 1e-6
                self.v[on, :2] *= np.exp(-cfg.floor_friction * h_sub)
        for c in self.colliders:
            c.prev_rotation, c.prev_translation = c.rotation.copy(), c.translation.copy()
        if not np.isfinite(self.x).all():
            raise FloatingPointError("the fluid diverged: a particle position is NaN or infinite")
        self.time += dt
        return n_sub


def _collider_travel(collider: Collider) -> float:
    """Farthest any point of the collider's field moves from its previous pose, m."""
    field = collider.sdf
    corners = field.origin + field.spacing * (
        np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
        * (np.array(field.values.shape) - 1)
    )
    before = corners @ collider.prev_rotation.T + collider.prev_translation
    after = corners @ collider.rotation.T + collider.translation
    return float(np.linalg.norm(after - before, axis=1).max())


def substep_poses(collider: PosedCollider, n_sub: int) -> tuple[np.ndarray, np.ndarray]:
    """The collider's poses at the substep boundaries of a step.

    From its previous pose to its current one: rotations (n_sub + 1, 3, 3) by slerp,
    translations (n_sub + 1, 3) linearly.
    """
    r0, t0 = collider.prev_rotation, collider.prev_translation
    r1, t1 = collider.rotation, collider.translation
    f = np.linspace(0.0, 1.0, n_sub + 1)
    trans = np.ascontiguousarray(t0 + f[:, None] * (t1 - t0))
    if np.array_equal(r0, r1):
        return np.ascontiguousarray(np.broadcast_to(r0, (n_sub + 1, 3, 3))), trans
    rot = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([r0, r1])))(f).as_matrix()
    # The end points are the poses as given, not their round trip through quaternions.
    rot[0], rot[-1] = r0, r1
    return np.ascontiguousarray(rot), trans
