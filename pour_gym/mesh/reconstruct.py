"""Chapter 3: point cloud -> implicit surface -> marching cubes -> Laplacian smoothing.

Two models of the unseen inner surface are offered (a scan sees only the outside):

- ``"thesis"``: the thesis's model. The Gaussian field is fitted on the scanned points alone;
  the object is where the field exceeds tau, a thin shell around the scanned surface, whose
  inner side stands in for the inner wall.
- ``"offset"`` (default): the scanned surface is the outside of a wall of known thickness.
  The same regression is fitted on the scan moved inward by half a wall along its normals
  (the middle of the wall), and the surface is the level of the field that the scanned
  points themselves take (their median). The shell then reaches from the scan to about one
  wall inside it, and its level sits well below the field's peak, so thin or sparse parts of
  the wall do not break up as they do at the thesis's fixed tau = 0.99.

The turntable hides the base, so the support plane inside the base's footprint is added to
the cloud (as the plane's points a real scanner segments away); without it no model can
hold water.

Marching cubes (scikit-image) runs on a grid of ``voxel`` (below half the wall, or the two
sides of the wall merge), masked to a band around the data, which keeps it from closing the
opening with a spurious lid; vertex normals come from the field's gradient. Laplacian
smoothing (trimesh) follows.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
import trimesh
from scipy import ndimage
from scipy.spatial import Delaunay
from skimage.measure import marching_cubes

from pour_gym.errors import InputError
from pour_gym.mesh.gaussian_field import GaussianField, fit_gaussian_field, voxel_means
from pour_gym.mesh.scan import PointCloud, estimate_normals

InnerModel = Literal["thesis", "offset"]


# Bumped when the same cloud reconstructs to another mesh (cached reconstructions go stale).
RECONSTRUCTION_VERSION = 1


@dataclass(frozen=True)
class ReconstructConfig:
    """Settings of the reconstruction.

    Attributes:
        sigma: width of the Gaussian kernel, in m (thesis: 0.01).
        tau: level of the surface (thesis: 0.99).
        regularization: lambda of each point relative to its row sum of the kernel matrix.
        cutoff: the kernel is tapered to zero between ``cutoff - 1`` and ``cutoff`` sigma.
        inducing_spacing: voxel edge for the inducing points, in m.
        voxel: marching-cubes grid spacing, in m.
        band: the field is evaluated within this distance of the data, in m.
        wall: wall thickness assumed by the ``"offset"`` model, in m.
        inner: model of the inner surface, ``"thesis"`` or ``"offset"``.
        support_plane: close the base with the turntable's plane.
        smoothing_iterations: Laplacian smoothing iterations (0 for none).
        smoothing_lambda: Laplacian smoothing step.
    """

    sigma: float = 0.01
    tau: float = 0.99
    regularization: float = 1e-3
    cutoff: float = 4.0
    inducing_spacing: float = 0.0025
    voxel: float = 0.00125
    band: float = 0.004
    wall: float = 0.004
    inner: InnerModel = "offset"
    support_plane: bool = True
    smoothing_iterations: int = 5
    smoothing_lambda: float = 0.5

    def to_dict(self) -> dict:
        """The settings as a JSON-serialisable dict."""
        return asdict(self)


@dataclass
class Reconstruction:
    """A reconstructed mesh and how it was made.

    Attributes:
        mesh: the surface, in m.
        field: the fitted implicit surface.
        n_points: points in the input cloud.
        n_inducing: inducing points the field was fitted on.
        seconds: wall-clock time per stage, in s.
        config: the settings used.
        level: the field's value on the surface (tau for the thesis model).
    """

    mesh: trimesh.Trimesh
    field: GaussianField
    n_points: int
    n_inducing: int
    seconds: dict[str, float]
    config: ReconstructConfig
    level: float


def validate_cloud(points: np.ndarray) -> np.ndarray:
    """Check a point cloud for the mistakes users make, and return it as float64.

    Args:
        points: (N, 3) positions, expected in m.

    Returns:
        The points as a contiguous float64 array.

    Raises:
        InputError: wrong shape, too few points, NaN or infinite values, or a size that
            cannot be a container in metres (millimetres, say).
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"a point cloud must be an (N, 3) array; got shape {pts.shape}")
    if len(pts) == 0:
        raise InputError("the point cloud is empty")
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise InputError(
            f"the point cloud has {int(bad.sum())} points with NaN or infinite coordinates; "
            "remove them before reconstructing"
        )
    if len(pts) < 100:
        raise InputError(f"the point cloud has only {len(pts)} points; at least 100 are needed")
    extent = float(np.ptp(pts, axis=0).max())
    if extent > 2.0:
        raise InputError(
            f"the point cloud is {extent:g} units across: that is not a container in metres. "
            "If it is in millimetres, scale it by 0.001 (--scale 0.001)"
        )
    if extent < 0.01:
        raise InputError(
            f"the point cloud is only {extent:g} m across; a container should be 0.01-2 m. "
            "Check its units (--scale)"
        )
    return np.ascontiguousarray(pts)


def _support_plane(points: np.ndarray, spacing: float) -> np.ndarray:
    """Points on the support plane inside the footprint of the cloud's lowest ring.

    The plane's height is a low percentile of the cloud's heights rather than the minimum,
    which the depth noise would push below the real base.
    """
    z0 = float(np.percentile(points[:, 2], 0.1))
    ring = points[points[:, 2] < z0 + 3.0 * spacing, :2]
    if len(ring) < 3:
        return np.zeros((0, 3))
    lo, hi = ring.min(axis=0), ring.max(axis=0)
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0], spacing), np.arange(lo[1], hi[1], spacing))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    try:
        inside = Delaunay(ring).find_simplex(grid) >= 0
    except Exception:  # a degenerate (collinear) footprint closes nothing
        return np.zeros((0, 3))
    return np.column_stack([grid[inside], np.full(int(inside.sum()), z0)])


def _ball(radius: int) -> np.ndarray:
    """Boolean ball structuring element of the given radius in voxels."""
    r = np.arange(-radius, radius + 1)
    return np.linalg.norm(np.stack(np.meshgrid(r, r, r, indexing="ij")), axis=0) <= radius


def _extract(
    fld: GaussianField, data: np.ndarray, level: float, cfg: ReconstructConfig
) -> trimesh.Trimesh:
    """Marching cubes on the field within a band around ``data``, then smoothing.

    The band starts at ``cfg.band`` around the data and grows wherever the field still
    exceeds ``level`` at its edge, so the surface is never cut open by the mask.
    """
    v = cfg.voxel
    growth = int(np.ceil(cfg.band / v))
    margin = 4 * cfg.band + 3 * v  # room for the band to grow three times
    lo = data.min(axis=0) - margin
    shape = np.ceil((data.max(axis=0) + margin - lo) / v).astype(int) + 1
    seed = np.zeros(shape, dtype=bool)
    idx = np.clip(np.round((data - lo) / v).astype(int), 0, shape - 1)
    seed[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    ball = _ball(growth)
    mask = ndimage.binary_dilation(seed, structure=ball)
    values = np.zeros(shape, dtype=np.float64)
    done = np.zeros(shape, dtype=bool)
    for _ in range(4):
        todo = mask & ~done
        cells = np.argwhere(todo)
        values[todo] = fld(lo + cells * v)
        done |= todo
        # A cube is skipped if any of its 8 corners is masked out, so the edge is taken
        # with the full 3x3x3 neighbourhood.
        edge = mask & ~ndimage.binary_erosion(mask, structure=np.ones((3, 3, 3), bool))
        spill = edge & (values > level)
        if not spill.any():
            break
        mask |= ndimage.binary_dilation(spill, structure=ball)
    if cfg.support_plane:
        # Nothing lies below the turntable: the field is cut at its plane.
        values[:, :, lo[2] + v * np.arange(shape[2]) < data[:, 2].min()] = 0.0
    if not (values > level).any():
        raise InputError(
            "the implicit surface has no inside at its level; lower the regularization or "
            "check the cloud"
        )
    verts, faces, normals, _ = marching_cubes(values, level=level, spacing=(v, v, v), mask=mask)
    mesh = trimesh.Trimesh(verts + lo, faces[:, ::-1], vertex_normals=normals, process=True)
    # Noise leaves specks where the field grazes tau; the object is the large components.
    parts = mesh.split(only_watertight=False)
    if len(parts) > 1:
        largest = max(len(p.faces) for p in parts)
        mesh = trimesh.util.concatenate([p for p in parts if len(p.faces) >= 0.01 * largest])
    if cfg.smoothing_iterations > 0:
        trimesh.smoothing.filter_laplacian(
            mesh, lamb=cfg.smoothing_lambda, iterations=cfg.smoothing_iterations
        )
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def reconstruct(
    cloud: PointCloud | np.ndarray, config: ReconstructConfig | None = None
) -> Reconstruction:
    """Reconstruct a closed surface mesh from a scan of an upright object.

    Args:
        cloud: the points (and outward normals, if known) in m, z up. Without normals they
            are estimated and oriented away from the vertical axis.
        config: settings; the default is the thesis's kernel with the ``"offset"`` model.

    Returns:
        The mesh with timings and the fitted field.

    Raises:
        InputError: the cloud is empty, has NaNs, is in the wrong units, or too small.
    """
    cfg = config or ReconstructConfig()
    if cfg.voxel > cfg.wall / 2.0 and cfg.inner == "offset":
        raise InputError(
            f"voxel {cfg.voxel} m is more than half the wall ({cfg.wall} m): the two sides "
            "of the wall would merge; use a smaller voxel"
        )
    if isinstance(cloud, PointCloud):
        points, normals = cloud.points, cloud.normals
    else:
        points, normals = cloud, None
    points = validate_cloud(points)
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    if normals is None or len(normals) != len(points):
        normals = estimate_normals(points, radius=2.5 * cfg.inducing_spacing)
    data, data_n = points, np.asarray(normals, dtype=np.float64)
    if cfg.support_plane:
        plane = _support_plane(points, cfg.inducing_spacing)
        data = np.concatenate([points, plane])
        data_n = np.concatenate([data_n, np.tile([0.0, 0.0, -1.0], (len(plane), 1))])
    seconds["prepare"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    train = data if cfg.inner == "thesis" else data - 0.5 * cfg.wall * data_n
    fld = fit_gaussian_field(
        voxel_means(train, cfg.inducing_spacing), cfg.sigma, cfg.regularization, cfg.cutoff
    )
    level = cfg.tau
    if cfg.inner == "offset":
        sample = np.random.default_rng(0).choice(len(data), min(5000, len(data)), replace=False)
        level = float(np.median(fld(data[sample])))
    seconds["fit"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    mesh = _extract(fld, data, level, cfg)
    seconds["marching_cubes"] = time.perf_counter() - t0
    return Reconstruction(
        mesh=mesh,
        field=fld,
        n_points=len(points),
        n_inducing=len(fld.centres),
        seconds=seconds,
        config=cfg,
        level=level,
    )
