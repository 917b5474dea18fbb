"""PourGym/Pour-v0: pour an amount of water from a held container into another."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from scipy.spatial.transform import Rotation

from pour_gym.envs.base import PourGymEnv
from pour_gym.features import ContainerGeometry
from pour_gym.fluid.pbf import PBFConfig
from pour_gym.sim import Camera

FEATURE_NAMES = (
    "lip_dx",  # (target rim centre - lip) along x, over the target's rim radius
    "lip_dy",  # the same along y
    "lip_height",  # lip above the target's rim centre, over the target's height
    "tilt",  # tilt of the source over 90 degrees
    "f3_source",  # fluid in the source over the source's volume (thesis f3)
    "f4_source",  # fluid in the source above its lip over its volume (thesis f4)
    "poured",  # particles in the target over the target amount
    "in_flight",  # moving particles in no container over the target amount
    "spilled",  # resting particles in no container over the target amount
    "target_fill",  # target amount over the target's volume
    "stream_f1",  # mean f1 of the particles in flight (0 if none)
    "target_rim_radius",  # in 10 cm
    "target_height",  # in 10 cm
    "source_rim_radius",  # in 10 cm
    "source_height",  # in 10 cm
)
STATE_NAMES = (
    "lip_x",
    "lip_y",
    "lip_z",
    "tilt_rad",
    "target_x",
    "target_y",
    "target_yaw_sin",
    "target_yaw_cos",
    "source_size_x",
    "source_size_y",
    "source_size_z",
    "target_size_x",
    "target_size_y",
    "target_size_z",
    "in_source",  # particle counts over the initial fill
    "poured",
    "in_flight",
    "spilled",
    "target_amount",
)
OBS_LIMIT = 10.0
UPRIGHT_DEG = 3.0
RESTING_SPEED = 0.05  # m/s: a particle in no container moving slower has spilled


class PourEnv(PourGymEnv):
    """Pour a target amount of water from a held container into one on the table.

    ## Description
    The proof of concept of the thesis's chapter 6 as a control task. A source container,
    filled with particle water, is held above the table with its lip (the rim point that
    faces the target, along +x) at a controlled position; a target container stands on
    the table at a random offset. The agent moves the lip and tilts the source about it
    to pour a requested amount into the target, spilling nothing, and sets the source
    upright again.

    ## Action Space
    ``Box(-1, 1, (4,))``: lip velocity along x, y, z (times ``max_speed`` m/s) and tilt
    rate (times ``max_tilt_rate`` degrees/s; positive tilts towards the target). The
    tilt stays within [0, ``max_tilt`` deg]; the lip stays in a box over the table and
    high enough that the source clears the target's rim.

    ## Observation Space
    ``obs_mode="features"`` (default): ``Box(-10, 10, (15,))``, see ``FEATURE_NAMES``:
    the lip relative to the target's rim centre in units of the target's rim radius and
    height, the tilt, the thesis's f3 and f4 of the source, the fluid poured, in flight
    and spilled over the target amount, the target amount over the target's volume, the
    stream's mean f1, and the containers' rim radii and heights from their labels.
    ``obs_mode="state"``: ``Box(-10, 10, (19,))``, see ``STATE_NAMES``: raw positions,
    tilt, the target's yaw, bounding-box sizes, particle counts over the initial fill;
    no warped features.

    ## Rewards
    Per step, with T the target amount in particles: ``progress`` = increase of
    min(poured, T) / T; ``overshoot`` = -2 times the increase of max(poured - T, 0) / T;
    ``spill`` = -2 times the increase of spilled particles / T; ``success`` = +1 on the
    step that ends a successful episode. ``info`` holds the terms; they sum to the reward.

    ## Starting State
    Containers from ``objects`` (or ``options``), sampled with ``np_random``; the source
    filled with ``source_particles`` (at most 60 % of its volume) and its lip 0-5 cm above
    the lowest allowed height at the origin; the target at x in [15, 25] cm, y in
    [-10, 10] cm with a random yaw; T uniform in ``amount_range`` (at most the fill less
    50 and 60 % of the target's volume).

    ## Episode End
    Terminated when some fluid has left the source, the source is upright again (tilt
    below 3 deg) and no particle is in flight, or when the source is empty and nothing is
    in flight. Success: |poured - T| <= max(5, 10 % of T), nothing spilled, source
    upright. Truncation is left to ``max_episode_steps`` (250 steps = 25 s).

    ## Arguments
    ``objects`` ("train", "test", "all", "real", a name, a mesh path or a list) for both
    containers, or ``source_objects`` / ``target_objects`` separately; ``obs_mode``;
    ``fluid`` ("pbf" or "bullet"); ``fluid_config`` (a ``PBFConfig`` or dict);
    ``source_particles``; ``amount_range``; ``max_speed``; ``max_tilt_rate``;
    ``max_tilt``; ``render_mode``. ``reset(options=...)`` accepts ``source``, ``target``
    (names or mesh paths) and ``target_amount`` (particles).

    ## Version History
    * v0: initial version.
    """

    def __init__(
        self,
        objects="train",
        source_objects=None,
        target_objects=None,
        obs_mode: str = "features",
        fluid: str = "pbf",
        fluid_config: PBFConfig | dict | None = None,
        source_particles: int = 1000,
        amount_range: tuple[int, int] = (100, 300),
        max_speed: float = 0.15,
        max_tilt_rate: float = 60.0,
        max_tilt: float = 135.0,
        render_mode: str | None = None,
    ):
        self._init_kwargs = dict(
            objects=objects,
            source_objects=source_objects,
            target_objects=target_objects,
            obs_mode=obs_mode,
            fluid=fluid,
            fluid_config=fluid_config,
            source_particles=source_particles,
            amount_range=amount_range,
            max_speed=max_speed,
            max_tilt_rate=max_tilt_rate,
            max_tilt=max_tilt,
            render_mode=render_mode,
        )
        self._check_obs_mode(obs_mode)
        if source_particles < 100:
            raise ValueError(f"source_particles must be at least 100, not {source_particles}")
        lo, hi = amount_range
        if not 1 <= lo <= hi:
            raise ValueError(f"amount_range must be (low, high) with 1 <= low <= high: {lo, hi}")
        self.sources = self._containers(source_objects if source_objects is not None else objects)
        self.targets = self._containers(target_objects if target_objects is not None else objects)
        self.obs_mode = obs_mode
        self.source_particles = int(source_particles)
        self.amount_range = (int(lo), int(hi))
        self.max_speed = float(max_speed)
        self.max_tilt_rate = float(max_tilt_rate)
        self.max_tilt = float(max_tilt)
        self.dt = 0.1
        self.substeps = 6
        names = FEATURE_NAMES if obs_mode == "features" else STATE_NAMES
        self.obs_names = names
        self.observation_space = spaces.Box(-OBS_LIMIT, OBS_LIMIT, (len(names),), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (4,), np.float32)
        self._setup(fluid, fluid_config, render_mode, Camera(distance=0.55, pitch=-30.0))

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode; ``options`` may fix ``source``, ``target``, ``target_amount``."""
        super().reset(seed=seed)
        options = self._options(options, {"source", "target", "target_amount"})
        source = self._choose(self.sources, options.get("source"))
        target = self._choose(self.targets, options.get("target"))
        placed = self._place({"source": source, "target": target})
        self.source, self.target = placed["source"], placed["target"]
        gs, gt = self.source.asset.geometry, self.target.asset.geometry
        rng = self.np_random
        # The target stands on the table; the source faces it with its lip (handle away).
        self.target_yaw = float(rng.uniform(-np.pi, np.pi))
        self.target_pos = np.array([rng.uniform(0.15, 0.25), rng.uniform(-0.1, 0.1), 0.0])
        rot_t = Rotation.from_euler("z", self.target_yaw).as_matrix()
        self.world.teleport(self.target, self.target_pos, rot_t)
        self._base_rot = Rotation.from_euler("z", np.pi).as_matrix()
        self._lip_local = np.array([gs.rim_center[0] - gs.rim_radius, gs.rim_center[1], gs.height])
        self.z_min = gt.height + gs.height + 0.01
        self.lip = np.array([0.0, 0.0, self.z_min + rng.uniform(0.0, 0.05)])
        self.tilt = 0.0
        self.world.teleport(self.source, *self._source_pose(self.lip, self.tilt))
        capacity_s = int(gs.cavity_volume / self.world.particle_volume)
        capacity_t = int(gt.cavity_volume / self.world.particle_volume)
        self.fill = min(self.source_particles, int(0.6 * capacity_s))
        hi = max(1, min(self.amount_range[1], self.fill - 50, int(0.6 * capacity_t)))
        lo = min(self.amount_range[0], hi)
        amount = options.get("target_amount")
        if amount is None:
            amount = int(rng.integers(lo, hi + 1))
        if not 1 <= int(amount) <= self.fill:
            raise ValueError(f"target_amount must be in [1, {self.fill}] particles, not {amount}")
        self.target_amount = int(amount)
        self.tolerance = max(5, round(0.1 * self.target_amount))
        self.world.fill(self.source, particles=self.fill)
        # The camera looks across the way from the source to the target.
        mid = 0.5 * (self.lip + self.target_pos)
        self.camera = Camera(
            target=(float(mid[0]), float(mid[1]), 0.1), distance=0.5, yaw=0.0, pitch=-20.0
        )
        self._poured_any = False
        self._counts = self._count()
        self._prev = self._counts
        return self._observation(), self._info(terms=None)

    def step(self, action):
        """Move and tilt the source for ``dt`` = 0.1 s of simulated time."""
        a = self._check_action(action)
        velocity = a[:3] * self.max_speed
        rate = a[3] * self.max_tilt_rate
        lo = np.array([-0.1, -0.3, self.z_min])
        hi = np.array([0.45, 0.3, 0.5])
        h = self.dt / self.substeps
        for _ in range(self.substeps):
            self.lip = np.clip(self.lip + velocity * h, lo, hi)
            self.tilt = float(np.clip(self.tilt + rate * h, 0.0, self.max_tilt))
            self.world.set_pose(self.source, *self._source_pose(self.lip, self.tilt))
            self.world.step(h)
        self._prev, self._counts = self._counts, self._count()
        c, p = self._counts, self._prev
        t = self.target_amount
        terms = {
            "progress": (min(c["poured"], t) - min(p["poured"], t)) / t,
            "overshoot": -2.0 * (max(c["poured"] - t, 0) - max(p["poured"] - t, 0)) / t,
            "spill": -2.0 * (c["spilled"] - p["spilled"]) / t,
            "success": 0.0,
        }
        if c["in_source"] < self.fill:
            self._poured_any = True
        settled = c["in_flight"] == 0
        upright = self.tilt < UPRIGHT_DEG
        terminated = bool(settled and ((self._poured_any and upright) or c["in_source"] == 0))
        success = terminated and self._succeeded()
        if success:
            terms["success"] = 1.0
        reward = float(sum(terms.values()))
        info = self._info(terms)
        info["is_success"] = success
        return self._observation(), reward, terminated, False, info

    # ------------------------------------------------------------------ helpers
    def _source_pose(self, lip: np.ndarray, tilt_deg: float):
        rot = Rotation.from_euler("y", tilt_deg, degrees=True).as_matrix() @ self._base_rot
        return lip - rot @ self._lip_local, rot

    def _count(self) -> dict[str, int]:
        census = self.world.census()
        self._where = census.where
        elsewhere = census.where < 0
        speed = np.linalg.norm(self.world.fluid.v, axis=1) if census.elsewhere else None
        moving = elsewhere & (speed > RESTING_SPEED) if speed is not None else elsewhere
        return {
            "in_source": int(census.counts[self.source.index]),
            "poured": int(census.counts[self.target.index]),
            "in_flight": int(np.count_nonzero(moving)),
            "spilled": int(np.count_nonzero(elsewhere & ~moving)),
        }

    def _succeeded(self) -> bool:
        c = self._counts
        return (
            abs(c["poured"] - self.target_amount) <= self.tolerance
            and c["spilled"] == 0
            and self.tilt < UPRIGHT_DEG
        )

    def _observation(self) -> np.ndarray:
        c = self._counts
        t = self.target_amount
        gs: ContainerGeometry = self.source.asset.geometry
        gt: ContainerGeometry = self.target.asset.geometry
        if self.obs_mode == "features":
            centre = self.target.to_world(gt.rim_center)
            x = self.world.particles
            census_where = self._where
            lip_z = self.lip[2]
            in_src = census_where == self.source.index
            above = np.count_nonzero(in_src & (x[:, 2] > lip_z))
            v = self.world.particle_volume
            flight = census_where < 0
            stream = 0.0
            if np.any(flight):
                d = np.hypot(x[flight, 0] - centre[0], x[flight, 1] - centre[1])
                stream = float(d.mean() / gt.rim_radius)
            obs = [
                (centre[0] - self.lip[0]) / gt.rim_radius,
                (centre[1] - self.lip[1]) / gt.rim_radius,
                (self.lip[2] - centre[2]) / gt.height,
                self.tilt / 90.0,
                c["in_source"] * v / gs.cavity_volume,
                above * v / gs.cavity_volume,
                c["poured"] / t,
                c["in_flight"] / t,
                c["spilled"] / t,
                t * v / gt.cavity_volume,
                stream,
                gt.rim_radius / 0.1,
                gt.height / 0.1,
                gs.rim_radius / 0.1,
                gs.height / 0.1,
            ]
        else:
            size_s = np.ptp(self.source.asset.mesh.bounds, axis=0)
            size_t = np.ptp(self.target.asset.mesh.bounds, axis=0)
            n0 = self.fill
            obs = [
                *self.lip,
                np.radians(self.tilt),
                self.target_pos[0],
                self.target_pos[1],
                np.sin(self.target_yaw),
                np.cos(self.target_yaw),
                *(size_s / 0.1),
                *(size_t / 0.1),
                c["in_source"] / n0,
                c["poured"] / n0,
                c["in_flight"] / n0,
                c["spilled"] / n0,
                t / n0,
            ]
        return np.clip(np.asarray(obs, dtype=np.float32), -OBS_LIMIT, OBS_LIMIT)

    def _info(self, terms: dict | None) -> dict:
        c = self._counts
        v_ml = self.world.particle_volume * 1e6
        info = {
            "source": self.source.asset.meta.get("_spec", self.source.asset.name),
            "target": self.target.asset.meta.get("_spec", self.target.asset.name),
            "target_amount": self.target_amount,
            "target_ml": self.target_amount * v_ml,
            "tolerance": self.tolerance,
            "fill": self.fill,
            **c,
            "poured_ml": c["poured"] * v_ml,
            "tilt_deg": self.tilt,
            "is_success": False,
        }
        if terms is not None:
            info.update({f"reward_{k}": v for k, v in terms.items()})
        return info

    def __repr__(self) -> str:
        return f"PourEnv(sources={self.sources}, targets={self.targets}, obs_mode={self.obs_mode})"
