"""Pictures of a world: pybullet's TinyRenderer for the bodies, particles splatted on top.

TinyRenderer runs headless on the CPU. The particles are not bodies (thousands of sphere
bodies would make every frame slow), so they are drawn after the bodies, as the sensors draw
them (:mod:`pour_gym.sim.raster`): spheres smoothed into one lit surface of water, hidden
where the depth buffer says a body is in front of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet

from pour_gym.sim.raster import composite_water, draw_spheres


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
        near: nearest depth drawn, m (a depth sensor's range starts here).
        far: farthest depth drawn, m (and where a depth sensor's range ends).
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

    def view(self) -> np.ndarray:
        """(4, 4) world-to-eye transform (OpenGL's: the camera looks along -z, y up)."""
        return np.asarray(self.matrices()[0], dtype=np.float64).reshape(4, 4).T

    def intrinsics(self) -> tuple[float, float, float]:
        """``(f, cx, cy)``: the focal length and principal point, pixels (square pixels)."""
        f = 0.5 * self.height / np.tan(np.radians(self.fov) / 2.0)
        return float(f), 0.5 * self.width, 0.5 * self.height


def to_eye(view: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, 3) world points in eye coordinates (float64, C-contiguous for the rasteriser)."""
    pts = np.asarray(points, dtype=np.float64)
    return np.ascontiguousarray(pts @ view[:3, :3].T + view[:3, 3])


def render(client, camera: Camera, particles: np.ndarray | None, radius: float) -> np.ndarray:
    """An RGB picture of the world with its particles.

    The bodies are pybullet's (TinyRenderer, so an arm is drawn too); the water is the
    sensors' (:func:`pour_gym.sim.raster.composite_water`): spheres of ``radius`` smoothed
    into one lit surface, hidden where a body is in front.

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
    n, far = camera.near, camera.far
    zbuf = np.asarray(depth, dtype=np.float64).reshape(h, w)
    # The depth buffer holds normalised device depth; eye-space distance is linear in 1/z.
    scene = far * n / (far - (far - n) * zbuf)
    f, cx, cy = camera.intrinsics()
    water = np.full((h, w), np.inf, dtype=np.float32)
    eye = to_eye(camera.view(), particles)
    draw_spheres(eye, radius, f, cx, cy, n, scene.astype(np.float32), water)
    composite_water(image, water, f, smooth_px=water_smoothing(radius, f, eye))
    return image


def water_smoothing(radius: float, f: float, eye: np.ndarray) -> float:
    """The water's smoothing, pixels: twice a drawn particle's radius at the median depth.

    Twice, so that neighbouring spheres' bumps are smoothed into one surface while a drop
    (a few particles) stays a drop.
    """
    if len(eye) == 0:
        return 0.0
    return float(2.0 * f * radius / max(float(np.median(-eye[:, 2])), 1e-3))
