"""PourGym/ParticleDrop-v0: will fluid released here end up in the container? (experiment 1)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle

from pour_gym.envs.base import PourGymEnv
from pour_gym.envs.observations import parse_obs_mode, vector_mode
from pour_gym.envs.task import DROP
from pour_gym.errors import InputError
from pour_gym.features import fill_fraction, relative_distance_height
from pour_gym.fluid.liquid import Liquid
from pour_gym.fluid.pbf import PBFConfig
from pour_gym.sim import Camera, Container
from pour_gym.sim.sensors import SensorConfig

FEATURE_NAMES = ("f1", "f2", "f3")
STATE_NAMES = ("x", "y", "z", "size_x", "size_y", "size_z", "fill")
OBS_NAMES = {"features": FEATURE_NAMES, "state": STATE_NAMES}
STATE_SCALE = 0.5  # m: positions and sizes in the state observation are over this


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
    ``Box(-1, 1, (1,), float32)``: release here if positive.

    ## Observation Space
    ``obs_mode="features"``: ``Box([0, -2, 0], [4, 3, 1], float32)``, the thesis's f1
    (horizontal distance to the rim centre over the rim radius), f2 (height above the rim
    centre over the container's height) and f3 (fluid in the container over its volume),
    from :mod:`pour_gym.features`. ``obs_mode="state"``: ``Box(-1, 1, (7,), float32)``:
    the blob's position relative to the container's base and the container's
    bounding-box size, both in units of 0.5 m, and the fill fraction. The sensor modes
    (``"depth"``, ``"rgb"``, ``"points"``, :mod:`pour_gym.sim.sensors`) see the container
    and the blob from a head camera above the table; a tuple of modes gives a ``Dict``.

    ## Rewards
    ``correct`` = 1 for a right decision; ``spill`` = -1 for releasing fluid that does not
    end in the container; 0 for holding back fluid that would have. Each times its
    weight; terms in ``info``.

    ## Starting State
    A container from ``objects`` (``np_random``); f1 uniform in [0, 2], f2 uniform in
    [0.05, 1], the azimuth uniform; the fill uniform in ``fill_range``.

    ## Episode End
    After the one step (terminated).

    ## Arguments
    | argument | type | default | meaning |
    |---|---|---|---|
    | ``objects`` | str, path or list | ``"train"`` | a split, names, mesh files, asset folders |
    | ``obs_mode`` | str or tuple | ``"features"`` | a mode (see above) or a tuple of them |
    | ``fluid`` | str | ``"pbf"`` | ``"pbf"`` or ``"bullet"`` |
    | ``fluid_config`` | PBFConfig or dict | None | fluid parameters |
    | ``num_threads`` | int or None | None | fluid threads |
    | ``blob`` | int | 1 | particles released |
    | ``fill_range`` | (float, float) | (0, 0.8) | resident fluid, fraction of the volume |
    | ``drop_time`` | float | 0.6 | simulated time after release, s |
    | ``correct_weight`` | float | 1.0 | weight of ``correct`` |
    | ``spill_weight`` | float | 2.0 | weight of ``spill`` |
    | ``render_mode`` | str or None | None | ``"rgb_array"`` or ``"human"`` |
    | ``sensor_config`` | SensorConfig or dict | None | image size, points, noise |
    | ``liquid`` | str, Liquid, dict or list | None | what is poured; a list or range: per episode |
    | ``spacing`` | float or None | None | particle spacing, m (2.5-7 mm; None: 5 mm) |

    ``reset(options=...)`` accepts ``container`` (a name or mesh path), ``spawn`` (xyz in
    the container's frame, m) and ``fill`` (fraction of the volume).

    The resident fluid enters f3 but is not simulated with the blob (it would cost a
    settling simulation per episode): the label is the blob's fate in the container as
    it stands, which is the per-particle question of the thesis as long as the container
    is not about to overflow (fills up to 80 % of the volume).

    ## Version History
    * (this release, every version) ``liquid`` added (``"water"``, ``"milk"``, ``"oil"``,
      ``"syrup"``, ``"honey"``, a :class:`~pour_gym.fluid.liquid.Liquid` or a list drawn
      from per episode, seeded;
      ``info["liquid"]``; docs/liquids.md): water, the default, is the fluid as it was, bit
      for bit; syrup and honey add a viscosity in its unit and walls that hold them.
      ``spacing`` added (the fluid's particle spacing, 2.5-7 mm; None keeps 5 mm, bit
      for bit).
    * v0 (this release): the sensor observation modes (``"depth"``, ``"rgb"``,
      ``"points"``, tuples of modes) and ``sensor_config`` (the defaults change nothing);
      the features from :mod:`pour_gym.features`; reward weights and
      ``num_threads`` are arguments; a user's mug of two overlapping bodies no longer
      leaves particles inside its base (its collision field is signed by where fluid
      can be, not by ray parity); a push out of a wall adds no more speed than the
      particle and the wall brought (see Pour-v0); the faster fluid kernel (see Pour-v0).
    * v0 (first release).
    """

    task = DROP

    def __init__(
        self,
        objects="train",
        obs_mode: str = "features",
        fluid: str = "pbf",
        fluid_config: PBFConfig | dict | None = None,
        num_threads: int | None = None,
        blob: int = 1,
        fill_range: tuple[float, float] = (0.0, 0.8),
        drop_time: float = 0.6,
        correct_weight: float = 1.0,
        spill_weight: float = 2.0,
        render_mode: str | None = None,
        sensor_config: SensorConfig | dict | None = None,
        liquid: str | Liquid | dict | list | None = None,
        spacing: float | None = None,
    ):
        EzPickle.__init__(
            self,
            objects=objects,
            obs_mode=obs_mode,
            fluid=fluid,
            fluid_config=fluid_config,
            num_threads=num_threads,
            blob=blob,
            fill_range=fill_range,
            drop_time=drop_time,
            correct_weight=correct_weight,
            spill_weight=spill_weight,
            render_mode=render_mode,
            sensor_config=sensor_config,
            liquid=liquid,
            spacing=spacing,
        )
        super().__init__(
            fluid,
            fluid_config,
            num_threads,
            render_mode,
            Camera(distance=0.4, pitch=-35.0),
            {"correct": correct_weight, "spill": spill_weight},
            sensor_config=sensor_config,
            liquid=liquid,
            spacing=spacing,
        )
        parse_obs_mode(obs_mode)  # a bad mode is named before any other argument
        if blob < 1:
            raise InputError(f"blob must be at least 1 particle, not {blob}")
        if not 0.0 <= fill_range[0] <= fill_range[1] <= 0.8:
            raise InputError(f"fill_range must lie within [0, 0.8], not {fill_range}")
        if not drop_time > 0:
            raise InputError(f"drop_time must be positive, not {drop_time}")
        self.containers = self._containers(objects)
        self.blob = int(blob)
        self.fill_range = (float(fill_range[0]), float(fill_range[1]))
        self.dt = float(drop_time)
        self._setup_observations(obs_mode)
        vector = vector_mode(self.obs_modes)
        self.obs_names = OBS_NAMES[vector] if vector else ()
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    @property
    def container(self) -> Container:
        """The episode's container."""
        return self._placed["container"]

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Place the container and the fluid; ``options``: container, spawn, fill."""
        super().reset(seed=seed)
        options = self._options(options, {"container", "spawn", "fill"})
        name = self._choose(self.containers, options.get("container"))
        self._place({"container": name})
        self.world.teleport(self.container, np.zeros(3))
        g = self.container.asset.geometry
        rng = self.np_random
        fill = options.get("fill")
        if fill is None:
            fill = rng.uniform(*self.fill_range)
        if not 0.0 <= float(fill) <= 0.8:
            raise InputError(f"fill is a fraction of the volume in [0, 0.8], not {fill}")
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
            raise InputError(f"spawn is 3 finite numbers (m, container frame), not {spawn!r}")
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
        self._features = self._compute_features()
        return self._observation(), self._info()

    def step(self, action):
        """Decide, then simulate the fluid for ``dt`` seconds and score the decision."""
        a = self._check_action(action)
        release = bool(a[0] > 0.0)
        # One world step: the container stands still, the fluid takes its own substeps.
        self.world.step(self.dt)
        census = self.world.census()
        self.label = bool(census.counts[self.container.index] * 2 > self.blob)
        terms = {
            "correct": float(release == self.label),
            "spill": -float(release and not self.label),
        }
        reward, weighted = self._reward(terms)
        info = self._info(weighted, label=self.label, released=release)
        return self._observation(), reward, True, False, info

    def features(self) -> np.ndarray:
        """(f1, f2, f3) of the fluid as it appeared."""
        return self._features.copy()

    def _compute_features(self) -> np.ndarray:
        c = self.container
        g = c.asset.geometry
        where = c.to_world(self.spawn)[None]
        f1, f2 = relative_distance_height(g, where, c.rotation, c.translation)
        return np.array([f1[0], f2[0], fill_fraction(self.fill * g.cavity_volume, g)])

    def _vector_space(self, mode: str) -> spaces.Box:
        if mode == "features":
            return spaces.Box(
                np.array([0.0, -2.0, 0.0], np.float32), np.array([4.0, 3.0, 1.0], np.float32)
            )
        return spaces.Box(-1.0, 1.0, (len(STATE_NAMES),), np.float32)

    def _vector_observation(self, mode: str) -> np.ndarray:
        if mode == "features":
            obs = self._features
        else:
            size = np.ptp(self.container.asset.surface.bounds, axis=0)
            obs = np.array([*(self.spawn / STATE_SCALE), *(size / STATE_SCALE), self.fill])
        space = self.obs_spaces[mode]
        return np.clip(obs, space.low, space.high).astype(np.float32)

    def _info(self, terms: dict | None = None, **outcome) -> dict:
        """The episode's info; after the step also the reward's terms and the outcome."""
        info = {
            "container": self._names["container"],
            "liquid": self.liquid.name,
            "features": self._features.tolist(),
            "spawn": self.spawn.tolist(),
            "fill": self.fill,
            **(terms or {}),
            **outcome,
        }
        info["is_success"] = bool(outcome) and outcome["released"] == outcome["label"]
        return info
