"""What a robot's head camera sees: depth, colour and a segmented point cloud.

A :class:`Sensor` draws the world's containers, its table and its fluid with the CPU
rasteriser of :mod:`pour_gym.sim.raster` (no display, no GPU) into a :class:`Frame`: z-depth,
a segment id per pixel and, when asked, colour. The observations are made from a frame:

- ``depth``: ``(H, W, 1)`` uint8, the depth mapped linearly from the depth range (the
  head camera's near and far, or ``depth_range``) onto 0..255 (255 also where nothing is
  seen), the form SB3's ``CnnPolicy`` takes;
- ``rgb``: ``(H, W, 3)`` uint8, the fluid drawn as one lit surface;
- ``points``: ``(4 N,)`` float32, N points back-projected from the depth image, each as
  (x, y, z in m, in the world frame or the source's frame; its segment id,
  :data:`SEGMENTS`), sampled to a fixed N; ``obs.reshape(-1, 4)`` gives the (N, 4) cloud.
  Flat, because SB3 takes a vector as it is (its ``check_env`` warns on an (N, 4) box).

Sensor noise (``depth_noise``, m) is added to the depth before both the depth image and the
points are made, so they agree. What the env draws besides its containers (the arm of
``holder="panda"``, its links as ``pybullet_data`` shapes them) comes as more bodies.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from gymnasium import spaces

from pour_gym.sim.camera import Camera, to_eye, water_smoothing
from pour_gym.sim.raster import (
    DRAWN_RADIUS,
    WATER_RGB,
    cluster_vertices,
    composite_water,
    draw_spheres,
    draw_triangles,
)

# A point's segment id: what it lies on.
SEGMENTS = {"source": 1, "target": 2, "fluid": 3, "table": 4, "arm": 5}
POINT_FRAMES = ("world", "source")
POINT_LIMIT = 2.0  # m: a point's coordinates are clipped to +-2 m (the sensor sees 1.5 m)
TABLE_HALF = 0.5  # m, the table's half side (pour_gym.sim.world's table)
SKY = np.array([235, 240, 245], dtype=np.uint8)
LIGHT = np.array([0.3, 0.6, 0.75]) / np.linalg.norm([0.3, 0.6, 0.75])


@dataclass(frozen=True)
class SensorConfig:
    """The head camera's image and point cloud.

    Attributes:
        width: image width, pixels.
        height: image height, pixels.
        fov: vertical field of view, degrees (None: the environment's head camera's).
        points: the point cloud's fixed number of points.
        points_frame: ``"world"`` or ``"source"`` (the source container's frame: its lip in
            Pour-v0, its base in the one-container envs).
        depth_range: (near, far) m: the sensor sees nothing nearer or farther, and the
            depth image maps this range onto 0..255 (None: the environment's head
            camera's, which spans its scene).
        depth_noise: standard deviation of Gaussian noise on each pixel's depth, m.
        splat: the fluid's drawn radius, in particle spacings (the pictures' by default:
            neighbours overlap, so the water reads as one body).
    """

    width: int = 84
    height: int = 84
    fov: float | None = None
    points: int = 1024
    points_frame: str = "world"
    depth_range: tuple[float, float] | None = None
    depth_noise: float = 0.0
    splat: float = DRAWN_RADIUS

    def __post_init__(self):
        if not (8 <= int(self.width) <= 1024 and 8 <= int(self.height) <= 1024):
            raise ValueError(
                f"sensor images are 8 to 1024 pixels a side, not {self.width} x {self.height}"
            )
        if self.fov is not None and not 10.0 <= self.fov <= 150.0:
            raise ValueError(f"the sensor's fov is 10 to 150 degrees, not {self.fov}")
        if int(self.points) < 1:
            raise ValueError(f"the point cloud needs at least 1 point, not {self.points}")
        if self.points_frame not in POINT_FRAMES:
            raise ValueError(
                f"points_frame must be one of {POINT_FRAMES}, not {self.points_frame!r}"
            )
        near, far = self.depth_range or (0.1, 1.0)
        if not 0.0 < near < far <= 2.0:
            raise ValueError(
                f"depth_range is (near, far) m with 0 < near < far <= 2, not {self.depth_range}"
            )
        if not 0.0 <= self.depth_noise < 0.1:
            raise ValueError(
                f"depth_noise is a standard deviation in [0, 0.1) m, not {self.depth_noise}"
            )
        if not 0.1 <= self.splat <= 3.0:
            raise ValueError(
                f"splat is the fluid's drawn radius in spacings, 0.1 to 3, not {self.splat}"
            )

    @classmethod
    def of(cls, config: SensorConfig | dict | None) -> SensorConfig:
        """A config from a config, a dict of its fields (ValueError naming a bad key), or None."""
        if config is None:
            return cls()
        if isinstance(config, cls):
            return config
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(config) - known)
        if unknown:
            raise ValueError(f"unknown sensor_config keys {unknown}; it takes {sorted(known)}")
        config = dict(config)
        if config.get("depth_range") is not None:
            config["depth_range"] = tuple(float(v) for v in config["depth_range"])
        return cls(**config)

    def to_dict(self) -> dict:
        """The fields as plain data (for EzPickle and JSON)."""
        return asdict(self)

    def space(self, mode: str) -> spaces.Box:
        """The observation space of a sensor mode."""
        h, w = int(self.height), int(self.width)
        if mode == "depth":
            return spaces.Box(0, 255, (h, w, 1), np.uint8)
        if mode == "rgb":
            return spaces.Box(0, 255, (h, w, 3), np.uint8)
        if mode == "points":
            n = int(self.points)
            low = np.tile(np.array([-POINT_LIMIT] * 3 + [0.0], np.float32), n)
            high = np.tile(np.array([POINT_LIMIT] * 3 + [max(SEGMENTS.values())], np.float32), n)
            return spaces.Box(low, high, dtype=np.float32)
        raise ValueError(f"the sensor modes are depth, rgb and points, not {mode!r}")


@dataclass
class Frame:
    """One picture of the world.

    Attributes:
        depth: (H, W) float64 z-depth, m; ``inf`` where nothing is seen within range.
        segment: (H, W) uint8 segment id (:data:`SEGMENTS`; 0 where nothing is seen).
        rgb: (H, W, 3) uint8 colour, or None if it was not asked for.
    """

    depth: np.ndarray
    segment: np.ndarray
    rgb: np.ndarray | None = None


@dataclass
class Body:
    """A container as the sensor draws it: its mesh, pose, segment and colour."""

    vertices: np.ndarray  # (V, 3) container frame, m
    faces: np.ndarray  # (F, 3) int64
    rotation: np.ndarray  # (3, 3)
    translation: np.ndarray  # (3,)
    segment: int
    color: tuple[float, float, float]


class Sensor:
    """A head camera over a world: frames, and the depth, rgb and points observations.

    Args:
        camera: where the camera stands and looks (its image size, and its fov if the
            config gives one, are replaced by the config's).
        config: image size, points, noise.
    """

    def __init__(self, camera: Camera, config: SensorConfig):
        self.config = config
        near, far = config.depth_range or (camera.near, camera.far)
        self.camera = Camera(
            target=camera.target,
            distance=camera.distance,
            yaw=camera.yaw,
            pitch=camera.pitch,
            width=int(config.width),
            height=int(config.height),
            fov=camera.fov if config.fov is None else config.fov,
            near=near,
            far=far,
        )
        self._view = self.camera.view()
        self._eye_to_world = np.linalg.inv(self._view)
        h, w = int(config.height), int(config.width)
        f, cx, cy = self.camera.intrinsics()
        # Each pixel's ray in eye coordinates (z = -1): the table and the back-projection.
        u = (np.arange(w) + 0.5 - cx) / f
        v = (cy - (np.arange(h) + 0.5)) / f
        self._rays = np.stack(np.broadcast_arrays(u[None, :], v[:, None], -np.ones((h, w))), -1)
        # Meshes are drawn merged on a grid of a pixel where the camera looks.
        self.cell = camera.distance / f
        self._table: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._light = self._view[:3, :3] @ LIGHT  # towards the light, eye coordinates

    def mesh(self, mesh) -> tuple[np.ndarray, np.ndarray]:
        """A container's mesh (trimesh) as this sensor draws it: merged to about a pixel."""
        return cluster_vertices(mesh.vertices, mesh.faces, self.cell, mesh.vertex_normals)

    def capture(
        self,
        bodies: list[Body],
        particles: np.ndarray,
        radius: float,
        table_color: tuple[float, float, float] | None,
        rng: np.random.Generator,
        rgb: bool = False,
        liquid_rgb: tuple[float, float, float] = tuple(WATER_RGB),
    ) -> Frame:
        """Draw the bodies, the table and the particles.

        Args:
            bodies: the containers to draw.
            particles: (N, 3) fluid particle positions, world frame, m.
            radius: drawn particle radius, m.
            table_color: the table's colour (a plane at z = 0, 1 m square), or None for no
                table.
            rng: the noise's generator (used only with ``depth_noise`` > 0).
            rgb: also paint colour.
            liquid_rgb: the liquid's colour, RGB in [0, 1].

        Returns:
            The frame; its depth carries the sensor's noise.
        """
        cam, cfg = self.camera, self.config
        h, w = cam.height, cam.width
        f, cx, cy = cam.intrinsics()
        near, far = cam.near, cam.far
        light = self._light
        if table_color is None:
            depth = np.full((h, w), np.inf, dtype=np.float32)
            seg = np.zeros((h, w), dtype=np.uint8)
            shade = np.zeros((h, w), dtype=np.float32)
        else:  # the camera stands still: the table's picture is the same every frame
            if self._table is None:
                self._table = self._draw_table(light)
            depth, seg, shade = (a.copy() for a in self._table)
        for body in bodies:
            model = np.eye(4)
            model[:3, :3], model[:3, 3] = body.rotation, body.translation
            draw_triangles(
                body.vertices, body.faces, self._view @ model, f, cx, cy, near,
                body.segment, depth, seg, light, shade,
            )  # fmt: skip
        water = np.full((h, w), np.inf, dtype=np.float32)
        eye_p = to_eye(self._view, particles) if len(particles) else np.zeros((0, 3))
        if len(eye_p):
            draw_spheres(eye_p, radius, f, cx, cy, near, depth, water)
        wet = np.isfinite(water)
        z = np.where(wet, water, depth).astype(np.float64)
        seg = np.where(wet, np.uint8(SEGMENTS["fluid"]), seg)
        if cfg.depth_noise > 0:
            seen = np.isfinite(z)
            z[seen] += rng.normal(0.0, cfg.depth_noise, int(seen.sum()))
        out = ~((z >= near) & (z <= far))
        z[out] = np.inf
        seg[out] = 0
        colour = None
        if rgb:
            colour = self._paint(bodies, table_color, seg, shade, wet)
            smooth = water_smoothing(radius, f, eye_p)
            composite_water(colour, np.where(wet & ~out, water, np.inf), f, smooth, liquid_rgb)
        return Frame(depth=z, segment=seg, rgb=colour)

    def _draw_table(self, light: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The table alone (a 1 m square at z = 0): depth, segments and shade buffers."""
        h, w = self._rays.shape[:2]
        depth = np.full((h, w), np.inf, dtype=np.float32)
        seg = np.zeros((h, w), dtype=np.uint8)
        shade = np.zeros((h, w), dtype=np.float32)
        origin = self._eye_to_world[:3, 3]
        dirs = self._rays @ self._eye_to_world[:3, :3].T
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -origin[2] / dirs[..., 2]
        hit = origin + t[..., None] * dirs
        on = (t > 0) & (np.abs(hit[..., 0]) <= TABLE_HALF) & (np.abs(hit[..., 1]) <= TABLE_HALF)
        depth[on] = t[on]  # the rays have z = -1 in eye space: t is the z-depth
        seg[on] = SEGMENTS["table"]
        up = self._view[:3, :3] @ np.array([0.0, 0.0, 1.0])
        shade[on] = 0.35 + 0.65 * abs(float(up @ light))
        return depth, seg, shade

    def _paint(self, bodies, table_color, seg, shade, wet) -> np.ndarray:
        colours = np.zeros((len(SEGMENTS) + 1, 3))
        for body in bodies:
            colours[body.segment] = body.color[:3]
        if table_color is not None:
            colours[SEGMENTS["table"]] = table_color[:3]
        solid = np.where(wet, 0, seg)  # under the water: painted by composite_water
        base = colours[solid] * shade[..., None] * 255.0
        rgb = np.where((solid > 0)[..., None], base, SKY[None, None, :].astype(np.float64))
        return np.clip(rgb, 0, 255).astype(np.uint8)

    # ------------------------------------------------------------------ observations
    def depth_image(self, frame: Frame) -> np.ndarray:
        """``(H, W, 1)`` uint8: depth over the depth range as 0..255 (255: nothing seen)."""
        near, far = self.camera.near, self.camera.far
        z = np.where(np.isfinite(frame.depth), frame.depth, far)
        scaled = np.rint((np.clip(z, near, far) - near) / (far - near) * 255.0)
        return scaled.astype(np.uint8)[..., None]

    def point_cloud(
        self,
        frame: Frame,
        rng: np.random.Generator,
        frame_pose: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """``(4 N,)`` float32: N seen points (x, y, z, segment id), sampled from the pixels.

        Args:
            frame: a captured frame.
            rng: chooses which pixels become points (with replacement only when fewer
                pixels than N saw something).
            frame_pose: ``(R, origin)`` of the frame the points are given in (world =
                R @ p + origin), or None for the world frame.

        Returns:
            The points, flat (``reshape(-1, 4)`` for the cloud); all zeros (segment 0) if
            nothing at all was seen.
        """
        n = int(self.config.points)
        seen = np.flatnonzero(np.isfinite(frame.depth))
        out = np.zeros((n, 4), dtype=np.float32)
        if len(seen) == 0:
            return out.reshape(-1)
        pick = np.sort(rng.choice(len(seen), n, replace=len(seen) < n))
        idx = seen[pick]
        z = frame.depth.reshape(-1)[idx]
        eye = self._rays.reshape(-1, 3)[idx] * z[:, None]
        world = eye @ self._eye_to_world[:3, :3].T + self._eye_to_world[:3, 3]
        if frame_pose is not None:
            rot, origin = frame_pose
            world = (world - origin) @ rot
        out[:, :3] = np.clip(world, -POINT_LIMIT, POINT_LIMIT)
        out[:, 3] = frame.segment.reshape(-1)[idx]
        return out.reshape(-1)
