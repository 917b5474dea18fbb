"""Signed-distance fields of container meshes, precomputed in the mesh's frame.

The fluid collides with a container by sampling its signed distance (negative inside the
wall's material) and the distance's gradient (the outward normal) at each particle, after
moving the particle into the container's frame with the container's current pose. The field
is a regular grid sampled trilinearly; it is computed once per mesh (open3d's ray-casting
scene, exact point-to-triangle distances with the sign from ray parity) and cached on disk.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numba as nb
import numpy as np

from pour_gym.errors import InputError
from pour_gym.io.cache import mesh_key, write_npz
from pour_gym.io.open3d_loader import open3d

if TYPE_CHECKING:  # trimesh takes 0.6 s to import; the fluid's processes need none
    import trimesh

    from pour_gym.mesh.surface import Surface

# The fast-math flags of the fluid's compiled code: every one but "reassoc". With
# reassociation LLVM may sum a particle's neighbours in another order wherever it inlines a
# function, so the kernel compiled in a process and the same kernel loaded from numba's
# on-disk cache gave different numbers, and so did its serial and parallel builds. Without
# it, the serial and parallel builds, compiled or cached, agree bit for bit
# (tests/test_fluid.py); docs/fluid.md gives what it costs.
FASTMATH = {"nnan", "ninf", "nsz", "arcp", "contract", "afn"}


def _no_refcount_option() -> dict:
    """``{"_nrt": False}`` where this numba compiles a function without its runtime.

    A compiled function that takes arrays counts references to them on every call (two
    atomic operations per array, in and out). The fluid's helpers are called once per
    particle, neighbour or wall sample, with up to nine arrays each: on one thread that
    bookkeeping is a large share of a step (docs/fluid.md). Functions compiled without the
    runtime may not allocate
    arrays (numba refuses to compile one that does, so this cannot go wrong silently);
    their callers hold the arrays alive.
    """
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:  # another numba: the kernel is only slower
        return {}
    return {"_nrt": False} if hasattr(CPUTargetOptions, "_nrt") else {}


# The options of every compiled helper that takes arrays and allocates none.
NO_REFCOUNT = _no_refcount_option()

# Whether the fluid kernel's parts (every function the kernel's drivers call) are kept in
# numba's on-disk cache on their own: never. Only the drivers are (with their parts linked
# in). A driver compiled while one of its parts came from the cache links that part as
# object code, which LLVM cannot inline, and under fast-math the result rounds differently
# from a driver compiled with the part at hand: the kernel built in two helper processes
# and the kernel compiled in one gave different particles. Parts compiled with their driver
# make every build the same, whoever compiled it and whatever was cached before
# (tests/test_precompile.py).
PART_CACHE = False


@dataclass(frozen=True)
class SignedDistanceField:
    """A signed distance on a grid, in the mesh's frame.

    Attributes:
        values: (nx, ny, nz) float32 signed distance in m at the grid nodes (negative in the
            material of the mesh). Single precision: a field of a cup is several million
            nodes that every fluid substep samples at random, so its size in the caches
            is what a sample costs; float32 resolves a distance to a few nanometres.
        origin: (3,) position of node (0, 0, 0), in m.
        spacing: node spacing, in m.
    """

    values: np.ndarray
    origin: np.ndarray
    spacing: float

    def __post_init__(self):
        object.__setattr__(self, "values", np.ascontiguousarray(self.values, dtype=np.float32))
        object.__setattr__(self, "origin", np.asarray(self.origin, dtype=np.float64))

    @property
    def flat(self) -> np.ndarray:
        """The values as one contiguous float32 run (x slowest, z fastest)."""
        return self.values.reshape(-1)

    @property
    def edge_min(self) -> float:
        """The smallest value on the grid's six faces, at least 0, m.

        Outside the grid :func:`trilinear` adds the distance to the grid's box to a value
        interpolated on a face, so a point outside is at least this plus that far from the
        material: a bound the fluid tests before it samples a field at all.
        """
        v = self.values
        faces = (v[0], v[-1], v[:, 0], v[:, -1], v[:, :, 0], v[:, :, -1])
        return max(0.0, float(min(f.min() for f in faces)))

    @functools.cached_property
    def corners(self) -> np.ndarray:
        """(8, 3) the corners of the grid's box in the mesh's frame, m."""
        lo, hi = self.origin, self.upper
        return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                         for z in (lo[2], hi[2])])  # fmt: skip

    @property
    def upper(self) -> np.ndarray:
        """(3,) position of the last node, m: the grid's box is ``origin`` to this."""
        return self.origin + self.spacing * (np.array(self.values.shape) - 1)

    def sample(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (N,) and its gradient (N, 3) at mesh-frame points."""
        p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        dist = np.empty(len(p))
        grad = np.empty((len(p), 3))
        nx, ny, nz = self.values.shape
        _sample_many(self.flat, nx, ny, nz, self.origin, self.spacing, p, dist, grad)
        return dist, grad


# How far from every surface a point must be to count as open space for the flood fill
# that decides which side of an open or multi-body mesh the fluid is on, m: half the wall a
# bare surface is given plus a particle's radius (5 mm particles), so the flood passes
# through exactly the gaps a particle could pass through.
OPEN_SPACE = 4e-3
SIGN_VERSION = 3  # bumped when the way fields are signed changes (cached fields go stale)


def build_sdf(
    mesh: trimesh.Trimesh | Surface,
    spacing: float = 1e-3,
    margin: float = 0.02,
    cache_dir: str | Path | None = None,
    min_wall: float = 3e-3,
) -> SignedDistanceField:
    """Compute (or load from the cache) the signed distance field of a container mesh.

    A single watertight body's material is its inside (the sign from ray parity). Any
    other mesh (a scan with holes, a surface with no thickness, a handle pushed into a
    body as a second piece whose open ends are buried in the wall) cannot be signed by
    parity: a point inside two overlapping pieces crosses an even number of surfaces. Its
    sign comes from where fluid can be instead: the open space reachable from far outside
    through gaps wider than a particle (a flood fill over points at least
    :data:`OPEN_SPACE` from every surface) and the points that see that space before a
    surface; everything else is material. Every surface of such a mesh is also thickened
    to a wall of ``min_wall``, so that the fluid meets a wall wherever the mesh has one.

    Args:
        mesh: the container, in m (a trimesh, or its arrays as a
            :class:`~pour_gym.mesh.surface.Surface`).
        spacing: grid spacing, in m (below half the wall thickness, so that the field
            resolves the wall).
        margin: the grid extends this far beyond the mesh's bounds, in m.
        cache_dir: folder for ``sdf_<hash>.npz`` files; ``None`` disables caching.
        min_wall: wall thickness given to the surfaces of a mesh that is not a single
            watertight body, m.

    Returns:
        The field.

    Raises:
        InputError: an empty mesh.
    """
    if len(mesh.faces) == 0:
        raise InputError("the mesh has no faces; a container needs a surface")
    solid = bool(mesh.is_watertight) and mesh.body_count == 1
    path = None
    if cache_dir is not None:
        key = mesh_key(mesh, spacing, margin, 0.0 if solid else min_wall, SIGN_VERSION)
        path = Path(cache_dir) / f"sdf_{key}.npz"
        if path.is_file():
            data = np.load(path)
            return SignedDistanceField(data["values"], data["origin"], float(data["spacing"]))
    o3d = open3d()
    lo, hi = mesh.bounds
    origin = lo - margin
    shape = np.ceil((hi - lo + 2 * margin) / spacing).astype(int) + 1
    axes = [origin[k] + spacing * np.arange(shape[k]) for k in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)),
    )
    query = o3d.core.Tensor(grid.astype(np.float32))
    if solid:
        # open3d's sign is negative inside the closed surface, which here is the material.
        values = scene.compute_signed_distance(query, nsamples=3).numpy().reshape(shape)
    else:
        distance = scene.compute_distance(query).numpy().astype(np.float64).reshape(shape)
        fluid_side = _fluid_side(distance, spacing)
        values = np.where(fluid_side, distance, -distance) - 0.5 * min_wall
    field = SignedDistanceField(values, origin, float(spacing))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_npz(path, values=field.values, origin=origin, spacing=spacing)
    return field


def _fluid_side(distance: np.ndarray, spacing: float) -> np.ndarray:
    """Which grid nodes lie on the fluid's side of the surfaces (see :func:`build_sdf`).

    Open space is flooded from the grid's faces over nodes at least :data:`OPEN_SPACE`
    from every surface. A node at distance d from the surfaces and e from that open space
    is on its side when e + d is about ``OPEN_SPACE`` (the open space lies straight
    beyond it, no surface between); behind a surface e + d is larger by twice the depth.

    Args:
        distance: (nx, ny, nz) unsigned distance to the nearest surface, m.
        spacing: node spacing, m.

    Returns:
        A boolean grid.
    """
    from scipy import ndimage

    deep = distance > OPEN_SPACE
    labels, _ = ndimage.label(deep)
    faces = (labels[0], labels[-1], labels[:, 0], labels[:, -1], labels[:, :, 0], labels[:, :, -1])
    outside = np.unique(np.concatenate([f.ravel() for f in faces]))
    open_space = np.isin(labels, outside[outside > 0])
    reach = ndimage.distance_transform_edt(~open_space, sampling=spacing)
    return open_space | (reach + distance <= OPEN_SPACE + spacing)


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH)
def _clamp_axis(x, origin, spacing, n):
    """Grid coordinate of x along one axis, clamped inside, and the distance clamped off."""
    u = (x - origin) / spacing
    hi = n - 1.000001
    if u < 0.0:
        return 0.0, -u * spacing
    if u > hi:
        return hi, (u - hi) * spacing
    return u, 0.0


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def trilinear(values, offset, nx, ny, nz, ox, oy, oz, spacing, x, y, z):
    """Trilinear signed distance and its unit gradient at a point of a field's frame.

    The field is stored flat (``values[offset:]``, x slowest, z fastest), so that the
    fields of several containers can travel to compiled code as one array. Outside the
    grid the distance to the grid's box is added to the nearest node's value, which keeps
    far particles far.

    Returns:
        ``(d, gx, gy, gz)``: distance in m and the gradient's direction (the outward
        normal of the nearest surface). One compiled version serves callers that need
        only the distance: a second, distance-only specialisation cost more compile time
        at first use than the few multiplications it saves.
    """
    extra = 0.0
    u, e = _clamp_axis(x, ox, spacing, nx)
    extra += e
    v, e = _clamp_axis(y, oy, spacing, ny)
    extra += e
    w, e = _clamp_axis(z, oz, spacing, nz)
    extra += e
    i, j, m = int(u), int(v), int(w)
    fx, fy, fz = u - i, v - j, w - m
    base = offset + (i * ny + j) * nz + m
    sx, sy = ny * nz, nz
    c000 = values[base]
    c100 = values[base + sx]
    c010 = values[base + sy]
    c110 = values[base + sx + sy]
    c001 = values[base + 1]
    c101 = values[base + sx + 1]
    c011 = values[base + sy + 1]
    c111 = values[base + sx + sy + 1]
    c00 = c000 * (1 - fx) + c100 * fx
    c10 = c010 * (1 - fx) + c110 * fx
    c01 = c001 * (1 - fx) + c101 * fx
    c11 = c011 * (1 - fx) + c111 * fx
    c0 = c00 * (1 - fy) + c10 * fy
    c1 = c01 * (1 - fy) + c11 * fy
    d = c0 * (1 - fz) + c1 * fz + extra
    gx = ((c100 - c000) * (1 - fy) + (c110 - c010) * fy) * (1 - fz) + (
        (c101 - c001) * (1 - fy) + (c111 - c011) * fy
    ) * fz
    gy = ((c010 - c000) * (1 - fx) + (c110 - c100) * fx) * (1 - fz) + (
        (c011 - c001) * (1 - fx) + (c111 - c101) * fx
    ) * fz
    gz = c1 - c0
    norm = np.sqrt(gx * gx + gy * gy + gz * gz)
    if norm > 1e-12:
        return d, gx / norm, gy / norm, gz / norm
    return d, 0.0, 0.0, 1.0


@nb.njit(cache=True)
def _sample_many(values, nx, ny, nz, origin, spacing, points, dist, grad):
    ox, oy, oz = origin[0], origin[1], origin[2]
    for i in range(points.shape[0]):
        d, gx, gy, gz = trilinear(
            values, 0, nx, ny, nz, ox, oy, oz, spacing, points[i, 0], points[i, 1], points[i, 2]
        )
        dist[i], grad[i, 0], grad[i, 1], grad[i, 2] = d, gx, gy, gz
