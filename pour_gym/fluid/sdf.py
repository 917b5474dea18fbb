"""Signed-distance fields of container meshes, precomputed in the mesh's frame.

The fluid collides with a container by sampling its signed distance (negative inside the
wall's material) and the distance's gradient (the outward normal) at each particle, after
moving the particle into the container's frame with the container's current pose. The field
is a regular grid sampled trilinearly; it is computed once per mesh (open3d's ray-casting
scene, exact point-to-triangle distances with the sign from ray parity) and cached on disk.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numba as nb
import numpy as np
import trimesh

from pour_gym.errors import InputError
from pour_gym.open3d_loader import open3d


@dataclass(frozen=True)
class SignedDistanceField:
    """A signed distance on a grid, in the mesh's frame.

    Attributes:
        values: (nx, ny, nz) float64 signed distance in m at the grid nodes (negative in the
            material of the mesh).
        origin: (3,) position of node (0, 0, 0), in m.
        spacing: node spacing, in m.
    """

    values: np.ndarray
    origin: np.ndarray
    spacing: float

    def sample(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (N,) and its gradient (N, 3) at mesh-frame points."""
        p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        dist = np.empty(len(p))
        grad = np.empty((len(p), 3))
        _sample_many(self.values, self.origin, self.spacing, p, dist, grad)
        return dist, grad


def _mesh_key(mesh: trimesh.Trimesh, *params: float) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    h.update(np.array(params, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def build_sdf(
    mesh: trimesh.Trimesh,
    spacing: float = 1e-3,
    margin: float = 0.02,
    cache_dir: str | Path | None = None,
    min_wall: float = 3e-3,
) -> SignedDistanceField:
    """Compute (or load from the cache) the signed distance field of a container mesh.

    A watertight mesh's material is its inside. A scanned mesh that is not watertight
    (small holes, a wall thinner than the grid) takes its sign from ray parity, and every
    surface is additionally thickened to a wall of ``min_wall``, so that the fluid meets a
    wall wherever the mesh has a surface.

    Args:
        mesh: the container, in m.
        spacing: grid spacing, in m (below half the wall thickness, so that the field
            resolves the wall).
        margin: the grid extends this far beyond the mesh's bounds, in m.
        cache_dir: folder for ``sdf_<hash>.npz`` files; ``None`` disables caching.
        min_wall: wall thickness given to the surfaces of a mesh that is not watertight, m.

    Returns:
        The field.

    Raises:
        InputError: an empty mesh.
    """
    if len(mesh.faces) == 0:
        raise InputError("the mesh has no faces; a container needs a surface")
    closed = bool(mesh.is_watertight)
    path = None
    if cache_dir is not None:
        key = _mesh_key(mesh, spacing, margin, 0.0 if closed else min_wall)
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
    # open3d's sign is negative inside the closed surface, which here is the material.
    query = o3d.core.Tensor(grid.astype(np.float32))
    values = scene.compute_signed_distance(query, nsamples=3).numpy().astype(np.float64)
    if not closed:
        shell = scene.compute_distance(query).numpy().astype(np.float64) - 0.5 * min_wall
        values = np.minimum(values, shell)
    field = SignedDistanceField(values.reshape(shape), origin, float(spacing))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, values=field.values, origin=origin, spacing=spacing)
    return field


@nb.njit(cache=True, inline="always")
def _clamp_axis(x, origin, spacing, n):
    """Grid coordinate of x along one axis, clamped inside, and the distance clamped off."""
    u = (x - origin) / spacing
    hi = n - 1.000001
    if u < 0.0:
        return 0.0, -u * spacing
    if u > hi:
        return hi, (u - hi) * spacing
    return u, 0.0


@nb.njit(cache=True)
def sample_sdf(values, origin, spacing, p, grad):
    """Trilinear signed distance at mesh-frame point ``p``; writes its gradient to ``grad``.

    Outside the grid the distance to the grid's box is added to the nearest node's value,
    which keeps far particles far.
    """
    # Scalars rather than small arrays: this runs for every particle in every substep.
    extra = 0.0
    u, e = _clamp_axis(p[0], origin[0], spacing, values.shape[0])
    extra += e
    v, e = _clamp_axis(p[1], origin[1], spacing, values.shape[1])
    extra += e
    w, e = _clamp_axis(p[2], origin[2], spacing, values.shape[2])
    extra += e
    i, j, m = int(u), int(v), int(w)
    fx, fy, fz = u - i, v - j, w - m
    c000 = values[i, j, m]
    c100 = values[i + 1, j, m]
    c010 = values[i, j + 1, m]
    c110 = values[i + 1, j + 1, m]
    c001 = values[i, j, m + 1]
    c101 = values[i + 1, j, m + 1]
    c011 = values[i, j + 1, m + 1]
    c111 = values[i + 1, j + 1, m + 1]
    c00 = c000 * (1 - fx) + c100 * fx
    c10 = c010 * (1 - fx) + c110 * fx
    c01 = c001 * (1 - fx) + c101 * fx
    c11 = c011 * (1 - fx) + c111 * fx
    c0 = c00 * (1 - fy) + c10 * fy
    c1 = c01 * (1 - fy) + c11 * fy
    d = c0 * (1 - fz) + c1 * fz
    gx = ((c100 - c000) * (1 - fy) + (c110 - c010) * fy) * (1 - fz) + (
        (c101 - c001) * (1 - fy) + (c111 - c011) * fy
    ) * fz
    gy = ((c010 - c000) * (1 - fx) + (c110 - c100) * fx) * (1 - fz) + (
        (c011 - c001) * (1 - fx) + (c111 - c101) * fx
    ) * fz
    gz = c1 - c0
    norm = np.sqrt(gx * gx + gy * gy + gz * gz)
    if norm > 1e-12:
        grad[0], grad[1], grad[2] = gx / norm, gy / norm, gz / norm
    else:
        grad[0], grad[1], grad[2] = 0.0, 0.0, 1.0
    return d + extra


@nb.njit(cache=True)
def _sample_many(values, origin, spacing, points, dist, grad):
    for i in range(points.shape[0]):
        dist[i] = sample_sdf(values, origin, spacing, points[i], grad[i])
