"""PourGym/ParticleDrop-v0: will fluid released here end up in the container? (experiment 1)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from pour_gym.envs.base import PourGymEnv
from pour_gym.fluid.pbf import PBFConfig
from pour_gym.sim import Camera

FEATURE_NAMES = ("f1", "f2", "f3")
STATE_NAMES = ("x", "y", "z", "size_x", "size_y", "size_z", "fill")
CORRECT, SPILL = 1.0, -2.0


class ParticleDropEnv(PourGymEnv):
    """Decide whether fluid appearing near a container should be released (thesis exp. 1).

    ## Description
    One container stands on the table. Fluid (a blob of ``blob`` particles, by default a
    single particle of a stream) appears at a random position around and above it; the
    container may already hold fluid (``fill_range``, a fraction of its volume). The
    agent decides in one step whether to release it here. The fluid is then simulated for
    ``drop_time`` seconds; the ground truth (``info["label"]``) is whether it increased the
    container's fluid volume (more than half of the blob ended in the container's cavity).
    A classifier of the features is a policy.

    ## Action Space
    ``Box(-1, 1, (1,))``: release here if positive.

    ## Observation Space
    ``obs_mode="features"``: ``Box([0, -2, 0], [4, 3, 1])``, the thesis's f1 (horizontal
    distance to the rim centre over the rim radius), f2 (height above the rim centre over
    the container's height) and f3 (fluid in the container over its volume).
    ``obs_mode="state"``: the blob's position relative to the container's base, m, the
    container's bounding-box size, m, and the fill fraction.

    ## Rewards
    ``correct`` = +1 for a right decision; ``spill`` = -2 for releasing fluid that does not
    end in the container; 0 for holding back fluid that would have. Terms in ``info``.

    ## Starting State
    A container from ``objects`` (``np_random``); f1 uniform in [0, 2], f2 uniform in
    [0.05, 1], the azimuth uniform; the fill uniform in ``fill_range``.

    ## Episode End
    After the one step (terminated).

    ## Arguments
    ``objects``, ``obs_mode``, ``fluid``, ``fluid_config``, ``blob`` (particles),
    ``fill_range``, ``drop_time`` (s), ``render_mode``. ``reset(options=...)`` accepts
    ``container`` (a name or mesh path), ``spawn`` (xyz in the container's frame, m) and
    ``fill`` (fraction of the volume).

    The resident fluid enters f3 but is not simulated with the blob (it would cost a
    settling simulation per episode): the label is the blob's fate in the container as
    it stands, which is the per-particle question of the thesis as long as the container
    is not about to overflow (fills up to 80 % of the volume).

    ## Version History
    * v0: initial version.
    """

    def __init__(
        self,
        objects="train",
        obs_mode: str = "features",
        fluid: str = "pbf",
        fluid_config: PBFConfig | dict | None = None,
        blob: int = 1,
        fill_range: tuple[float, float] = (0.0, 0.8),
        drop_time: float = 0.6,
        render_mode: str | None = None,
    ):
        self._init_kwargs = dict(
            objects=objects,
            obs_mode=obs_mode,
            fluid=fluid,
            fluid_config=fluid_config,
            blob=blob,
            fill_range=fill_range,
            drop_time=drop_time,
            render_mode=render_mode,
        )
        self._check_obs_mode(obs_mode)
        if blob < 1:
            raise ValueError(f"blob must be at least 1 particle, not {blob}")
        if not 0.0 <= fill_range[0] <= fill_range[1] <= 0.8:
            raise ValueError(f"fill_range must lie within [0, 0.8], not {fill_range}")
        self.containers = self._containers(objects)
        self.obs_mode = obs_mode
        self.blob = int(blob)
        self.fill_range = (float(fill_range[0]), float(fill_range[1]))
        self.dt = float(drop_time)
        if obs_mode == "features":
            self.obs_names = FEATURE_NAMES
            self.observation_space = spaces.Box(
                np.array([0.0, -2.0, 0.0], np.float32), np.array([4.0, 3.0, 1.0], np.float32)
            )
        else:
            self.obs_names = STATE_NAMES
            self.observation_space = spaces.Box(-1.0, 1.0, (len(STATE_NAMES),), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self._setup(fluid, fluid_config, render_mode, Camera(distance=0.4, pitch=-35.0))

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Place the container and the fluid; ``options``: container, spawn, fill."""
        super().reset(seed=seed)
        options = self._options(options, {"container", "spawn", "fill"})
        name = self._choose(self.containers, options.get("container"))
        self.container = self._place({"container": name})["container"]
        self.world.teleport(self.container, np.zeros(3))
        g = self.container.asset.geometry
        rng = self.np_random
        fill = options.get("fill")
        if fill is None:
            fill = rng.uniform(*self.fill_range)
        if not 0.0 <= float(fill) <= 0.8:
            raise ValueError(f"fill is a fraction of the volume in [0, 0.8], not {fill}")
        self.fill = float(fill)
        spawn = options.get("spawn")
        if spawn is None:
            f1, f2 = rng.uniform(0.0, 2.0), rng.uniform(0.05, 1.0)
            phi = rng.uniform(-np.pi, np.pi)
            spawn = g.rim_center + np.array(
                [f1 * g.rim_radius * np.cos(phi), f1 * g.rim_radius * np.sin(phi), f2 * g.height]
            )
        spawn = np.asarray(spawn, dtype=np.float64)
        if spawn.shape != (3,) or not np.isfinite(spawn).all():
            raise ValueError(f"spawn is 3 finite numbers (m, container frame), not {spawn!r}")
        self.spawn = spawn
        s = self.fluid_config.spacing
        # A compact blob: the lattice points nearest the spawn point.
        k = int(np.ceil(np.cbrt(self.blob))) + 1
        offsets = (
            np.stack(np.meshgrid(*[np.arange(k)] * 3, indexing="ij"), -1).reshape(-1, 3)
            - (k - 1) / 2
        ) * s
        offsets = offsets[np.argsort(np.linalg.norm(offsets, axis=1), kind="stable")][: self.blob]
        self.world.add_particles(self.container.to_world(spawn + offsets))
        return self._observation(), self._info()

    def step(self, action):
        """Decide, then simulate the fluid for ``dt`` seconds and score the decision."""
        a = self._check_action(action)
        release = bool(a[0] > 0.0)
        # One world step: the container stands still, the fluid takes its own substeps.
        self.world.step(self.dt)
        census = self.world.census()
        self.label = bool(census.counts[self.container.index] * 2 > self.blob)
        terms = {"correct": 0.0, "spill": 0.0}
        if release == self.label:
            terms["correct"] = CORRECT
        elif release:
            terms["spill"] = SPILL
        info = self._info()
        info.update({f"reward_{k}": v for k, v in terms.items()})
        info.update(label=self.label, released=release, is_success=release == self.label)
        return self._observation(), float(sum(terms.values())), True, False, info

    def features(self) -> np.ndarray:
        """(f1, f2, f3) of the fluid as it appeared."""
        g = self.container.asset.geometry
        d = self.spawn - g.rim_center
        return np.array([np.hypot(d[0], d[1]) / g.rim_radius, d[2] / g.height, self.fill])

    def _observation(self) -> np.ndarray:
        if self.obs_mode == "features":
            obs = self.features()
        else:
            size = np.ptp(self.container.asset.mesh.bounds, axis=0)
            obs = np.array([*(self.spawn / 0.5), *(size / 0.5), self.fill])
        space = self.observation_space
        return np.clip(obs, space.low, space.high).astype(np.float32)

    def _info(self) -> dict:
        return {
            "container": self.container.asset.meta.get("_spec", self.container.asset.name),
            "features": self.features().tolist(),
            "spawn": self.spawn.tolist(),
            "fill": self.fill,
            "is_success": False,
        }
