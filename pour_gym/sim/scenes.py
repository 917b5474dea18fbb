"""Scripted scenes of a world: a container tilted about its lip to pour into another.

Used for the pouring video of the README and for checks of the world as a whole; the
Gymnasium environments drive the same world through actions instead.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pour_gym.sim.camera import Camera
from pour_gym.sim.world import CUP_COLORS, World


@dataclass(frozen=True)
class PourScript:
    """A pour: tilt up to ``angle`` degrees, hold, and tilt back upright.

    Attributes:
        angle: largest tilt, degrees.
        tilt_time: seconds to tilt up.
        hold_time: seconds at the largest tilt.
        back_time: seconds to tilt back.
        rest_time: seconds upright at the end.
    """

    angle: float = 110.0
    tilt_time: float = 2.5
    hold_time: float = 1.0
    back_time: float = 1.5
    rest_time: float = 1.0

    @property
    def duration(self) -> float:
        """Seconds of the whole pour."""
        return self.tilt_time + self.hold_time + self.back_time + self.rest_time

    def angle_at(self, t: float) -> float:
        """Tilt at time ``t`` seconds, degrees (smooth at both ends of each ramp)."""

        def ease(u: float) -> float:
            u = min(max(u, 0.0), 1.0)
            return u * u * (3.0 - 2.0 * u)

        if t < self.tilt_time:
            return self.angle * ease(t / self.tilt_time)
        t -= self.tilt_time + self.hold_time
        if t < 0:
            return self.angle
        return self.angle * (1.0 - ease(t / self.back_time))


@dataclass
class PourOutcome:
    """What a scripted pour did (particle counts)."""

    source: int
    target: int
    elsewhere: int
    frames: list[np.ndarray]


def tilt_about(lip: np.ndarray, base: np.ndarray, axis: np.ndarray, angle_deg: float):
    """The pose that tilts a container about its lip point.

    Args:
        lip: (3,) the lip point in the container's frame, m.
        base: (3,) the upright container's position, m.
        axis: (3,) tilt axis in the world (unit).
        angle_deg: tilt, degrees.

    Returns:
        ``(position, rotation)`` with the lip point where it is when upright.
    """
    rot = Rotation.from_rotvec(np.radians(angle_deg) * np.asarray(axis)).as_matrix()
    return base + lip - rot @ lip, rot


def scripted_pour(
    source: str = "red_cup",
    target: str = "broad_cup",
    particles: int = 1500,
    fluid: str = "pbf",
    script: PourScript | None = None,
    fps: int = 20,
    camera: Camera | None = None,
    progress: Callable[[float], None] | None = None,
) -> PourOutcome:
    """Pour from a held source container into a target on the table.

    The source is held with its lip above the target's rim, on the side towards the
    target, and tilted about the lip.

    Args:
        source: catalogue name or asset directory of the held container.
        target: the container on the table.
        particles: fluid in the source at the start.
        fluid: ``"pbf"`` or ``"bullet"``.
        script: the tilt over time.
        fps: frames per simulated second to render (0: none).
        camera: view for the frames.
        progress: called with the fraction done after every step.

    Returns:
        The particle counts at the end and the frames.
    """
    script = script or PourScript()
    world = World(fluid)
    try:
        tgt = world.add_container(target, (0.0, 0.0, 0.0), color=CUP_COLORS[1])
        g_t = tgt.asset.geometry
        src = world.add_container(source, (0.0, 0.0, 1.0), color=CUP_COLORS[0])
        g_s = src.asset.geometry
        # The lip faces the target (+x from the source) and sits inside the target's rim;
        # the source's base is a centimetre above the target, so that they never touch.
        lip = np.array([g_s.rim_center[0] + g_s.rim_radius, g_s.rim_center[1], g_s.height])
        over = np.array(
            [
                g_t.rim_center[0] - 0.7 * g_t.rim_radius,
                g_t.rim_center[1],
                g_t.height + g_s.height + 0.01,
            ]
        )
        base = over - lip
        world.teleport(src, base)
        world.fill(src, particles=particles)
        camera = camera or Camera(
            target=(float(over[0]) - 0.02, 0.0, float(g_t.height)), distance=0.42, yaw=20.0
        )
        frames = []
        dt = 1.0 / 60.0
        steps = round(script.duration / dt)
        every = max(round(60 / fps), 1) if fps else 0
        for k in range(steps):
            angle = script.angle_at((k + 1) * dt)
            world.set_pose(src, *tilt_about(lip, base, np.array([0.0, 1.0, 0.0]), angle))
            world.step(dt)
            if every and k % every == 0:
                frames.append(world.render(camera))
            if progress is not None:
                progress((k + 1) / steps)
        c = world.census()
        return PourOutcome(
            source=int(c.counts[src.index]),
            target=int(c.counts[tgt.index]),
            elsewhere=c.elsewhere,
            frames=frames,
        )
    finally:
        world.close()
