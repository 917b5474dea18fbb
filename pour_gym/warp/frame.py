"""Put any container mesh into a canonical frame: upright, on z = 0, handle along +x.

A user's mesh comes in any pose and size. The frame is found from the shape alone:

1. Upright: of the directions along the principal axes of the vertices and their
   bisectors, the one that makes the mesh hold the most water (a flood fill of its
   voxelised surface) is up.
   The rim's plane, fitted to the top band, then refines the axis.
2. Origin: the rim centre's vertical line is the z axis; the lowest vertex is at z = 0.
3. Azimuth: a handle is a range of azimuths where the mesh reaches much farther from the
   axis than elsewhere; if there is one, it is turned to +x.

Normalised coordinates divide x, y by the body's radius at that height and z by the height,
so that two containers of different proportions and flare line up wall to wall, rim to rim
and base to base, which is what label transfer needs (thesis 4.2 aligns by part centres and
per-axis spread instead).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from pour_gym.errors import NoWaterError
from pour_gym.mesh.measure import (
    azimuth_wedges,
    max_per_group,
    rim_band_mask,
    shell_holding_volume,
    surface_samples,
    top_band_rim,
)


@dataclass(frozen=True)
class ContainerFrame:
    """A rigid transform into the canonical frame and the container's size in it.

    Attributes:
        transform: (4, 4) matrix taking the input's coordinates to the canonical frame.
        height: rim top above the base, in m.
        rim_radius: mean distance of the top band to the rim centre, in m.
        handle: whether a handle was found (then it points along +x).
        profile: (B, 2) body radius against height, (z, rho) in m, in the canonical frame.
        rim_top: (W, 2) height of the rim's top against azimuth, (angle in rad, z in m);
            a scanned rim is seldom level, and normalising by it keeps the rim band even.
    """

    transform: np.ndarray
    height: float
    rim_radius: float
    handle: bool
    profile: np.ndarray
    rim_top: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Points (N, 3) in the input's coordinates to the canonical frame."""
        return points @ self.transform[:3, :3].T + self.transform[:3, 3]

    def rotate(self, vectors: np.ndarray) -> np.ndarray:
        """Directions (N, 3) in the input's coordinates to the canonical frame."""
        return vectors @ self.transform[:3, :3].T

    def normalise(self, points: np.ndarray) -> np.ndarray:
        """Canonical-frame points to (x / rho(z), y / rho(z), z / H).

        rho(z) is the body's outer radius at height z (see :func:`body_profile`), so that
        walls of any flare line up at |(x, y)| = 1 and rims at z = 1.
        """
        rho = self._rho(points[:, 2])
        top = self._top(points)
        return np.column_stack([points[:, 0] / rho, points[:, 1] / rho, points[:, 2] / top])

    def normalise_normals(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Unit normals at canonical-frame ``points`` under the normalising scale."""
        rho = self._rho(points[:, 2])
        n = normals * np.column_stack([rho, rho, self._top(points)])
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)

    def _rho(self, z: np.ndarray) -> np.ndarray:
        return np.interp(z, self.profile[:, 0], self.profile[:, 1])

    def _top(self, points: np.ndarray) -> np.ndarray:
        return top_at(points, self.rim_top)


def _rotation_to_z(direction: np.ndarray) -> np.ndarray:
    """Rotation matrix taking the unit ``direction`` onto +z."""
    d = direction / np.linalg.norm(direction)
    return trimesh.geometry.align_vectors(d, [0.0, 0.0, 1.0])[:3, :3]


def _rotz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _held(samples: np.ndarray, rotation: np.ndarray, voxel: float) -> float:
    return shell_holding_volume(samples @ rotation.T, voxel)


def find_up(mesh: trimesh.Trimesh) -> np.ndarray:
    """The rotation that turns a container upright, found by which way it holds water.

    Args:
        mesh: the container in any orientation, in m.

    Returns:
        (3, 3) rotation matrix; after it, the opening faces +z.

    Raises:
        NoWaterError: the mesh holds no water in any of the candidate directions.
    """
    v = np.asarray(mesh.vertices, dtype=float)
    centred = v - v.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    size = float(np.ptp(centred, axis=0).max())
    voxel = size / 40.0
    # The surface is sampled once; each candidate orientation only rotates the samples.
    samples = surface_samples(mesh, 0.4 * voxel) - v.mean(axis=0)
    # The principal axes and their pairwise bisectors: no direction is more than about 35
    # degrees from a candidate, which the rim-plane refinement below can close (a mug's
    # handle can tilt its principal axes by 45 degrees from its own axis).
    candidates = list(axes)
    for i in range(3):
        for j in range(i + 1, 3):
            candidates += [(axes[i] + axes[j]) / np.sqrt(2), (axes[i] - axes[j]) / np.sqrt(2)]
    best, best_volume = None, 0.0
    for axis in candidates:
        for sign in (1.0, -1.0):
            rot = _rotation_to_z(sign * axis)
            volume = _held(samples, rot, voxel)
            if volume > best_volume:
                best, best_volume = rot, volume
    if best is None:
        raise NoWaterError(
            "the mesh holds no water in any orientation: it is not a container, or its "
            "opening is closed (scans often close it: cut the cap off at the rim)"
        )
    # Refine: the rim's plane is level when the container stands upright. The band is
    # taken per azimuth wedge, so it is a whole loop even while the axis is still tilted.
    for _ in range(10):
        up = centred @ best.T
        mask, _ = rim_band_mask(up, band=0.03 * float(np.ptp(up[:, 2])))
        band = up[mask]
        if len(band) < 10:
            break
        normal = np.linalg.svd(band - band.mean(axis=0), full_matrices=False)[2][2]
        if normal[2] < 0:
            normal = -normal
        # A band that is not a loop says nothing about the axis: only moderate corrections,
        # and only while they do not spill water.
        if normal[2] < np.cos(np.radians(45.0)):
            break
        if normal[2] > np.cos(np.radians(0.05)):
            break  # level
        candidate = _rotation_to_z(normal) @ best
        volume = _held(samples, candidate, voxel)
        if volume < 0.95 * best_volume:
            break
        best, best_volume = candidate, max(volume, best_volume)
    # Polish by hill climbing on the held water: a rim band that caught part of a handle
    # can settle a few degrees off, and an upright cup holds the most.
    for step in (8.0, 4.0, 2.0, 1.0):
        improved = True
        while improved:
            improved = False
            for axis in ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0)):
                tilt = Rotation.from_rotvec(np.radians(step) * np.array(axis)).as_matrix()
                candidate = tilt @ best
                volume = _held(samples, candidate, voxel)
                if volume > 1.005 * best_volume:
                    best, best_volume, improved = candidate, volume, True
                    break
    return best


def _handle_azimuth(points: np.ndarray, rim_radius: float) -> float | None:
    """Azimuth of a handle in an upright frame centred on the rim axis, or None."""
    z = points[:, 2]
    h = np.ptp(z)
    mid = points[(z > 0.1 * h) & (z < 0.9 * h)]
    if len(mid) < 10:
        return None
    r = np.hypot(mid[:, 0], mid[:, 1])
    bins = 72
    az, idx = azimuth_wedges(mid, bins)
    reach = np.maximum(max_per_group(idx, r, bins), 0.0)
    excess = reach - np.median(reach)
    if excess.max() < 0.25 * rim_radius:
        return None
    far = r > np.median(reach) + 0.5 * excess.max()
    return float(np.arctan2(np.sin(az[far]).mean(), np.cos(az[far]).mean()))


def body_profile(points: np.ndarray, bins: int = 40, wedges: int = 36) -> np.ndarray:
    """Outer radius of the body against height, ignoring a handle.

    In each height bin the largest distance from the z axis is taken per azimuth wedge, and
    the median over the wedges is the body's radius there (a handle fills a few wedges
    only).

    Args:
        points: (N, 3) canonical-frame positions (upright, axis at x = y = 0).
        bins: number of height bins.
        wedges: number of azimuth wedges.

    Returns:
        (bins, 2) array of (z, rho) in m, rho positive and smoothed over neighbouring bins.
    """
    z = points[:, 2]
    r = np.hypot(points[:, 0], points[:, 1])
    edges = np.linspace(z.min(), z.max(), bins + 1)
    zb = np.clip(np.searchsorted(edges, z, side="right") - 1, 0, bins - 1)
    _, wb = azimuth_wedges(points, wedges)
    best = max_per_group(zb * wedges + wb, r, bins * wedges)
    reach = np.where(np.isfinite(best), best, np.nan).reshape(bins, wedges)
    rho = np.nanmedian(np.where(np.isnan(reach).all(axis=1, keepdims=True), 0.0, reach), axis=1)
    rho = np.convolve(np.pad(rho, 1, mode="edge"), np.ones(3) / 3.0, mode="valid")
    rho = np.maximum(rho, 0.05 * rho.max())
    return np.column_stack([(edges[:-1] + edges[1:]) / 2.0, rho])


def rim_heights(points: np.ndarray, wedges: int = 36) -> np.ndarray:
    """Height of the rim's top per azimuth wedge, smoothed over neighbouring wedges.

    Args:
        points: (N, 3) canonical-frame positions.
        wedges: number of wedges.

    Returns:
        (wedges, 2) array of (azimuth of the wedge centre in rad, height in m).
    """
    _, wb = azimuth_wedges(points, wedges)
    top = max_per_group(wb, points[:, 2], wedges)
    # A wedge without a rim vertex (coarse meshes) or with a dip takes its neighbours' mean.
    good = np.isfinite(top)
    low = top < np.median(top[good]) - 0.1 * float(np.ptp(points[:, 2]))
    good &= ~low
    idx = np.arange(wedges)
    top = np.interp(idx, idx[good], top[good], period=wedges)
    top = (np.roll(top, 1) + top + np.roll(top, -1)) / 3.0
    centres = -np.pi + (idx + 0.5) * 2 * np.pi / wedges
    return np.column_stack([centres, top])


def top_at(points: np.ndarray, rim_top: np.ndarray) -> np.ndarray:
    """Height of the rim's top at each point's azimuth, in m.

    Args:
        points: (N, 3) canonical-frame positions.
        rim_top: (W, 2) azimuth and top height per wedge, as :func:`rim_heights` gives.

    Returns:
        (N,) heights, interpolated between the wedges' centres around the circle.
    """
    az = np.arctan2(points[:, 1], points[:, 0])
    return np.interp(az, rim_top[:, 0], rim_top[:, 1], period=2 * np.pi)


def canonical_frame(mesh: trimesh.Trimesh, upright: bool = False) -> ContainerFrame:
    """Find the canonical frame of a container mesh.

    Args:
        mesh: the container, in m, in any pose (or already upright with ``upright``).
        upright: skip the search for up (the mesh's +z is up).

    Returns:
        The frame.
    """
    v = np.asarray(mesh.vertices, dtype=float)
    rot = np.eye(3) if upright else find_up(mesh)
    up = v @ rot.T
    centre, radius, top = top_band_rim(up)
    shift = np.array([-centre[0], -centre[1], -up[:, 2].min()])
    placed = up + shift
    azimuth = _handle_azimuth(placed, radius)
    spin = _rotz(-azimuth) if azimuth is not None else np.eye(3)
    transform = np.eye(4)
    transform[:3, :3] = spin @ rot
    transform[:3, 3] = spin @ shift
    return ContainerFrame(
        transform=transform,
        height=top - float(up[:, 2].min()),
        rim_radius=radius,
        handle=azimuth is not None,
        profile=body_profile(placed @ spin.T),
        rim_top=rim_heights(placed @ spin.T),
    )
