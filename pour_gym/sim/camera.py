"""Pictures of a world: pybullet's TinyRenderer for the bodies, particles splatted on top.

TinyRenderer runs headless on the CPU. The particles are not bodies (thousands of sphere
bodies would make every frame slow), so they are drawn after the bodies as shaded discs,
each hidden where the depth buffer says a body is in front of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet

WATER = np.array([0.20, 0.45, 0.90])


@dataclass(frozen=True)
class Camera:
    """A camera looking at a point.

    Attributes:
        target: (x, y, z) point looked at, m.
        distance: from the target, m.
        yaw: about the vertical, degrees.
        pitch: elevation (negative looks down), degrees.
        width: image width, pixels.
        height: image height, pixels.
        fov: vertical field of view, degrees.
    """

    target: tuple[float, float, float] = (0.0, 0.0, 0.1)
    distance: float = 0.45
    yaw: float = 30.0
    pitch: float = -25.0
    width: int = 480
    height: int = 360
    fov: float = 45.0
    near: float = 0.02
    far: float = 3.0

    def matrices(self) -> tuple[list[float], list[float]]:
        """Pybullet's view and projection matrices (column-major, 16 floats each)."""
        view = pybullet.computeViewMatrixFromYawPitchRoll(
            list(self.target), self.distance, self.yaw, self.pitch, 0.0, 2
        )
        proj = pybullet.computeProjectionMatrixFOV(
            self.fov, self.width / self.height, self.near, self.far
        )
        return view, proj


def render(client, camera: Camera, particles: np.ndarray | None, radius: float) -> np.ndarray:
    """An RGB picture of the world with its particles.

    Args:
        client: the world's pybullet client.
        camera: where to look from.
        particles: (N, 3) particle positions, m, or None.
        radius: drawn particle radius, m.

    Returns:
        (height, width, 3) uint8 image.
    """
    view, proj = camera.matrices()
    w, h = camera.width, camera.height
    _, _, rgba, depth, _ = client.getCameraImage(
        w,
        h,
        viewMatrix=view,
        projectionMatrix=proj,
        renderer=pybullet.ER_TINY_RENDERER,
        flags=pybullet.ER_NO_SEGMENTATION_MASK,
        lightDirection=[0.4, -0.6, 1.0],
        shadow=0,
    )
    image = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3].copy()
    if particles is None or len(particles) == 0:
        return image
    n, f = camera.near, camera.far
    zbuf = np.asarray(depth, dtype=np.float64).reshape(h, w)
    # The depth buffer holds normalised device depth; eye-space distance is linear in 1/z.
    scene_depth = f * n / (f - (f - n) * zbuf)
    v = np.asarray(view).reshape(4, 4).T
    p = np.asarray(proj).reshape(4, 4).T
    pts = np.c_[np.asarray(particles, dtype=np.float64), np.ones(len(particles))]
    eye = pts @ v.T
    clip = eye @ p.T
    dist = -eye[:, 2]
    ok = dist > n
    ndc = clip[ok, :2] / clip[ok, 3:4]
    px = (ndc[:, 0] + 1.0) * 0.5 * w
    py = (1.0 - ndc[:, 1]) * 0.5 * h
    rpx = radius * p[1, 1] * 0.5 * h / dist[ok]
    d = dist[ok]
    # Far to near, so that nearer particles cover farther ones.
    for k in np.argsort(-d):
        r = max(rpx[k], 0.8)
        x0, x1 = int(max(px[k] - r, 0)), int(min(px[k] + r + 1, w))
        y0, y1 = int(max(py[k] - r, 0)), int(min(py[k] + r + 1, h))
        if x0 >= x1 or y0 >= y1:
            continue
        yy, xx = np.mgrid[y0:y1, x0:x1]
        u = (xx + 0.5 - px[k]) / r
        t = (yy + 0.5 - py[k]) / r
        rr = u * u + t * t
        visible = (rr <= 1.0) & (d[k] - radius < scene_depth[y0:y1, x0:x1])
        if not visible.any():
            continue
        # A sphere lit from the upper left: brighter towards its lit side.
        nz = np.sqrt(np.clip(1.0 - rr, 0.0, 1.0))
        shade = np.clip(0.55 + 0.45 * (nz * 0.8 - u * 0.3 - t * 0.3), 0.3, 1.2)
        colour = np.clip(WATER[None, None, :] * shade[..., None] * 255.0, 0, 255)
        patch = image[y0:y1, x0:x1]
        patch[visible] = colour[visible].astype(np.uint8)
    return image
