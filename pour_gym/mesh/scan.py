"""A simulated turntable depth scan (thesis 3.1: a Kinect looking at a turning table).

A pinhole depth camera looks at the object's centre from a fixed distance while the object
turns in equal steps; each step ray-casts one depth image. Depth noise is Gaussian along
the ray. As in the thesis, only the outside is captured: the turntable hides the base, and
with ``outside_only`` hits on the inner surface (ground-truth label ``container``) are
dropped, because the thesis's scanner produced no inner points. Normals are estimated from
the cloud, as PCL does, and oriented toward the camera that saw each point.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import trimesh

from pour_gym.errors import InputError
from pour_gym.io.open3d_loader import open3d
from pour_gym.parts import Part


@dataclass(frozen=True)
class ScanConfig:
    """Settings of the simulated scanner.

    Attributes:
        views: turntable steps per revolution.
        elevations_deg: camera elevations above the table, one revolution each, in deg.
        distance: camera distance from the object's centre, in m.
        width: image width in pixels.
        height: image height in pixels.
        fov_deg: horizontal field of view, in deg (a Kinect has 57).
        noise: standard deviation of the depth noise along each ray, in m.
        outside_only: drop hits on the inner surface (needs ground-truth labels).
        normal_radius: neighbourhood radius for normal estimation, in m.
        seed: seed of the depth noise.
    """

    views: int = 24
    elevations_deg: tuple[float, ...] = (5.0, 30.0)
    distance: float = 0.45
    width: int = 200
    height: int = 150
    fov_deg: float = 57.0
    noise: float = 0.0005
    outside_only: bool = True
    normal_radius: float = 0.006
    seed: int = 0

    def to_dict(self) -> dict:
        """The settings as a JSON-serialisable dict."""
        return asdict(self)


@dataclass
class PointCloud:
    """A point cloud with outward normals.

    Attributes:
        points: (N, 3) positions in m.
        normals: (N, 3) unit normals pointing out of the object, or ``None``.
        meta: provenance (how it was made), JSON-serialisable.
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    meta: dict = field(default_factory=dict)


def _camera_rays(cfg: ScanConfig, eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(H*W, 6) rays of a pinhole camera at ``eye`` looking at ``target``, z up."""
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    f = 0.5 * cfg.width / np.tan(np.radians(cfg.fov_deg) / 2.0)
    u = (np.arange(cfg.width) + 0.5 - cfg.width / 2.0) / f
    v = (np.arange(cfg.height) + 0.5 - cfg.height / 2.0) / f
    uu, vv = np.meshgrid(u, -v)
    d = forward + uu[..., None] * right + vv[..., None] * up
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.column_stack([np.broadcast_to(eye, d.shape), d]).astype(np.float32)


def turntable_scan(
    mesh: trimesh.Trimesh,
    labels: np.ndarray | None = None,
    config: ScanConfig | None = None,
) -> PointCloud:
    """Scan a mesh on a turntable with a simulated depth camera.

    Args:
        mesh: the object, upright (z up), in m; it is turned about the vertical axis
            through its bounding-box centre.
        labels: per-vertex part labels; with ``config.outside_only`` hits on faces whose
            vertices are all ``container`` are dropped. Without labels every hit is kept.
        config: scanner settings.

    Returns:
        The merged cloud in the object's frame, with normals estimated from the points and
        oriented toward the camera.

    Raises:
        InputError: the mesh is empty, or the camera saw nothing.
    """
    cfg = config or ScanConfig()
    if len(mesh.faces) == 0:
        raise InputError("cannot scan an empty mesh")
    o3d = open3d()
    rng = np.random.default_rng(cfg.seed)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)),
    )
    inner_face = None
    if cfg.outside_only and labels is not None:
        inner_face = np.all(np.asarray(labels)[mesh.faces] == Part.CONTAINER, axis=1)
    lo, hi = mesh.bounds
    centre = (lo + hi) / 2.0
    points, eyes = [], []
    for elevation in cfg.elevations_deg:
        el = np.radians(elevation)
        for k in range(cfg.views):
            az = 2.0 * np.pi * k / cfg.views
            # Turning the object by -az is the same as moving the camera by +az.
            eye = centre + cfg.distance * np.array(
                [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
            )
            rays = _camera_rays(cfg, eye, centre)
            hit = scene.cast_rays(o3d.core.Tensor(rays))
            t = hit["t_hit"].numpy()
            keep = np.isfinite(t)
            if inner_face is not None:
                prim = hit["primitive_ids"].numpy()
                keep &= ~inner_face[np.where(keep, prim, 0)]
            t = t[keep] + rng.normal(0.0, cfg.noise, size=int(keep.sum()))
            p = rays[keep, :3] + t[:, None] * rays[keep, 3:]
            points.append(p)
            eyes.append(np.broadcast_to(eye, p.shape))
    pts = np.concatenate(points).astype(np.float64)
    if len(pts) == 0:
        raise InputError("the simulated camera saw nothing: check the mesh's size and units (m)")
    cam = np.concatenate(eyes)
    normals = estimate_normals(pts, cfg.normal_radius, viewpoints=cam)
    return PointCloud(
        points=pts,
        normals=normals,
        meta={"source": "turntable_scan", "config": cfg.to_dict(), "n_points": len(pts)},
    )


def estimate_normals(
    points: np.ndarray, radius: float, viewpoints: np.ndarray | None = None
) -> np.ndarray:
    """Unit normals from local plane fits, oriented toward the viewpoints or outward.

    Args:
        points: (N, 3) positions in m.
        radius: neighbourhood radius in m (at most 30 neighbours are used).
        viewpoints: (N, 3) camera position that saw each point; without them normals are
            made consistent over a tangent-plane graph and then flipped to point away from
            the cloud's vertical axis on average.

    Returns:
        (N, 3) unit normals.
    """
    o3d = open3d()
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=float)))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=30))
    n = np.asarray(pcd.normals).copy()
    if viewpoints is not None:
        flip = np.einsum("ij,ij->i", n, viewpoints - points) < 0.0
        n[flip] *= -1.0
        return n
    pcd.orient_normals_consistent_tangent_plane(15)
    n = np.asarray(pcd.normals).copy()
    axis = np.asarray(points).mean(axis=0)
    radial = np.asarray(points) - axis
    radial[:, 2] = 0.0
    if np.einsum("ij,ij->i", n, radial).mean() < 0.0:
        n *= -1.0
    return n
