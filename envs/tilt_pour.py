"""PourGym/TiltPour-v0: will the container pour when tilted to this angle? (experiment 2)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle

from pour_gym.envs.base import PourGymEnv
from pour_gym.envs.observations import parse_obs_mode, vector_mode
from pour_gym.envs.task import TILT
from pour_gym.errors import InputError
from pour_gym.features import cavity_points, fluid_features, mouth_volume
from pour_gym.fluid.liquid import Liquid
from pour_gym.fluid.pbf import PBFConfig
from pour_gym.sim import Camera
from pour_gym.sim.rotations import from_rotvec
from pour_gym.sim.sensors import SEGMENTS, SensorConfig
from pour_gym.sim.spawn import cavity_lattice

LABEL_MODES = ("hydrostatic", "simulate")
# Tilting is about the world y axis through the container's base, the top towards -x
# (away from the handle, which the assets keep along +x).
AXIS = np.array([0.0, -1.0, 0.0])
TILT_TIME, HOLD_TIME = 6.0, 1.0  # s, for the simulated label
STATE_LIMIT = 4.0  # the state observation's bound (sizes in 10 cm, a wide bowl is ~2)
OBS_NAMES = {"features": ("f4",), "state": ("tilt_rad", "fill", "size_x", "size_y", "size_z")}


class TiltPourEnv(PourGymEnv):
    """Decide whether a filled container tilted slowly to an angle will pour (thesis exp. 2).

    ## Description
    A container is filled to a random fraction of its volume and tilted slowly about a
    fixed horizontal axis to a random angle. The agent predicts in one step whether fluid
    leaves it; the ground truth is in ``info["label"]``. As in the thesis, the feature f4
    is computed from the fluid at rest upright, rotated with the container to the angle:
    the fluid above the lip (the lowest rim vertex) over the container's volume
    (:func:`pour_gym.features.fluid_features`).

    ``label_mode="hydrostatic"`` (default) labels by the quasi-static limit the thesis's
    "tilted slowly" describes: the water pours when its volume exceeds what the tilted
    cavity holds below the lowest point of its mouth (the inner edge of the rim, which
    water must pass; :func:`pour_gym.features.mouth_volume`). On straight cylinders this
    flips within 1 degree of tan(theta) = (H - h) / R (``tests/test_envs.py``).
    ``label_mode="simulate"`` tilts the particle fluid over 6 s and holds 1 s, and labels
    by whether 2 or more particles left.

    ## Action Space
    ``Box(-1, 1, (1,), float32)``: positive predicts that the container pours.

    ## Observation Space
    ``obs_mode="features"``: ``Box(0, 1, (1,), float32)``, f4. ``obs_mode="state"``:
    ``Box(-4, 4, (5,), float32)``: the tilt angle (rad), the fill fraction and the
    container's bounding-box size (in 10 cm). The sensor modes (``"depth"``, ``"rgb"``,
    ``"points"``, :mod:`pour_gym.sim.sensors`) see the tilted container from a head camera
    looking into its mouth, with its fluid as the label's quasi-static limit has it: the
    fill at rest, rotated with the container (the same fluid as f4's). A tuple of modes
    gives a ``Dict``.

    ## Rewards
    ``correct`` = 1 for a right prediction; ``spill`` = -1 for predicting no pour when it
    pours; 0 for a false alarm. Each times its weight; terms in ``info``.

    ## Starting State
    A container from ``objects``; the fill uniform in ``fill_range`` (fraction of the
    volume); the angle uniform in ``tilt_range`` (degrees).

    ## Episode End
    After the one step (terminated).

    ## Arguments
    | argument | type | default | meaning |
    |---|---|---|---|
    | ``objects`` | str, path or list | ``"train"`` | a split, names, mesh files, asset folders |
    | ``obs_mode`` | str or tuple | ``"features"`` | a mode (see above) or a tuple of them |
    | ``fluid`` | str | ``"pbf"`` | ``"pbf"`` or ``"bullet"`` (simulated labels) |
    | ``fluid_config`` | PBFConfig or dict | None | fluid parameters |
    | ``num_threads`` | int or None | None | fluid threads (simulated labels) |
    | ``label_mode`` | str | ``"hydrostatic"`` | ``"hydrostatic"`` or ``"simulate"`` |
    | ``fill_range`` | (float, float) | (0.2, 0.9) | fill, fraction of the volume |
    | ``tilt_range`` | (float, float) | (0, 90) | tilt, degrees |
    | ``correct_weight`` | float | 1.0 | weight of ``correct`` |
    | ``spill_weight`` | float | 2.0 | weight of ``spill`` |
    | ``render_mode`` | str or None | None | ``"rgb_array"`` or ``"human"`` |
    | ``sensor_config`` | SensorConfig or dict | None | image size, points, noise |
    | ``liquid`` | str, Liquid, dict or list | None | what is poured; a list or range: per episode |
    | ``spacing`` | float or None | None | particle spacing, m (2.5-7 mm; None: 5 mm) |

    ``reset(options=...)`` accepts ``container``, ``fill`` and ``tilt_deg``.

    ## Version History
    * (this release, every version) ``liquid`` added (``"water"``, ``"milk"``, ``"oil"``,
      ``"syrup"``, ``"honey"``, a :class:`~pour_gym.fluid.liquid.Liquid` or a list drawn
      from per episode, seeded;
      ``info["liquid"]``; docs/liquids.md): water, the default, is the fluid as it was, bit
      for bit; syrup and honey add a viscosity in its unit and walls that hold them.
    * v0 (this release): the sensor observation modes (``"depth"``, ``"rgb"``,
      ``"points"``, tuples of modes) and ``sensor_config`` (the defaults change nothing);
      the hydrostatic label measures from the mouth's lowest point (it
      measured from the lowest rim vertex, the outer edge of a thick rim, and called pours
      4 degrees early); f4 from :mod:`pour_gym.features`; reward weights and
      ``num_threads`` are arguments; a push out of a wall adds no more speed than the
      particle and the wall brought (see Pour-v0); the faster fluid kernel (see Pour-v0).
    * v0 (first release).
    """

    task = TILT
    # The container is the one that pours: the source's segment. The camera looks from
    # above into the mouth as it tilts (towards -x), where the water meets the lip.
    role_segments: ClassVar[dict[str, int]] = {"container": SEGMENTS["source"]}
    head_camera = Camera(
        target=(-0.04, 0.0, 0.05), distance=0.25, yaw=-90.0, pitch=-35.0, fov=45.0, near=0.05,
        far=0.6,
    )  # fmt: skip

    def __init__(
        self,
        objects="train",
        obs_mode: str = "features",
        fluid: str = "pbf",
        fluid_config: PBFConfig | dict | None = None,
        num_threads: int | None = None,
        label_mode: str = "hydrostatic",
        fill_range: tuple[float, float] = (0.2, 0.9),
        tilt_range: tuple[float, float] = (0.0, 90.0),
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
            label_mode=label_mode,
            fill_range=fill_range,
            tilt_range=tilt_range,
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
            Camera(distance=0.4, pitch=-20.0),
            {"correct": correct_weight, "spill": spill_weight},
            steps_fluid=label_mode == "simulate",
            sensor_config=sensor_config,
            liquid=liquid,
            spacing=spacing,
        )
        parse_obs_mode(obs_mode)  # a bad mode is named before any other argument
        if label_mode not in LABEL_MODES:
            raise InputError(f"label_mode must be one of {LABEL_MODES}, not {label_mode!r}")
        if not 0.0 < fill_range[0] <= fill_range[1] <= 1.0:
            raise InputError(f"fill_range must lie within (0, 1], not {fill_range}")
        if not 0.0 <= tilt_range[0] <= tilt_range[1] <= 180.0:
            raise InputError(f"tilt_range must lie within [0, 180] degrees, not {tilt_range}")
        self.containers = self._containers(objects)
        self.label_mode = label_mode
        self.fill_range = (float(fill_range[0]), float(fill_range[1]))
        self.tilt_range = (float(tilt_range[0]), float(tilt_range[1]))
        self.dt = TILT_TIME + HOLD_TIME
        self._setup_observations(obs_mode)
        vector = vector_mode(self.obs_modes)
        self.obs_names = OBS_NAMES[vector] if vector else ()
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        # Per container, computed once: the rest lattice (it never enters the world in the
        # hydrostatic mode) and the cavity's voxel centres.
        self._lattices: dict[str, np.ndarray] = {}
        self._voxels: dict[str, np.ndarray] = {}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Choose container, fill and angle; ``options``: container, fill, tilt_deg."""
        super().reset(seed=seed)
        options = self._options(options, {"container", "fill", "tilt_deg"})
        rng = self.np_random
        self.name = self._choose(self.containers, options.get("container"))
        asset, sdf = self._load(self.name)
        if self.name not in self._lattices:
            spacing = self.fluid_config.spacing
            self._lattices[self.name] = cavity_lattice(asset.geometry, sdf, spacing)
            self._voxels[self.name] = cavity_points(asset.geometry)
        fill = options.get("fill")
        fill = rng.uniform(*self.fill_range) if fill is None else float(fill)
        if not 0.0 < fill <= 1.0:
            raise InputError(f"fill is a fraction of the volume in (0, 1], not {fill}")
        tilt = options.get("tilt_deg")
        tilt = rng.uniform(*self.tilt_range) if tilt is None else float(tilt)
        if not (np.isfinite(tilt) and 0.0 <= tilt <= 180.0):
            raise InputError(f"tilt_deg must be in [0, 180], not {tilt}")
        self.fill, self.tilt = fill, tilt
        lattice = self._lattices[self.name]
        g = asset.geometry
        v = self.fluid_config.particle_volume
        self.count = min(len(lattice), max(1, round(fill * g.cavity_volume / v)))
        self.rest = lattice[: self.count]
        self.rotation = from_rotvec(np.radians(tilt) * AXIS)
        self.episode_asset = asset
        # The thesis's f4: the fluid at rest upright, rotated with the container (all of
        # it counts as in the container), above the lowest rim vertex.
        self.f4 = fluid_features(
            g, self.rest @ self.rotation.T, self.rotation, np.zeros(3), v,
            inside=np.ones(self.count, dtype=bool),
        )[1]  # fmt: skip
        self._world_ready = False
        return self._observation(), self._info()

    def step(self, action):
        """Predict, then label the tilt (hydrostatically or by simulation) and score it."""
        a = self._check_action(action)
        predict = bool(a[0] > 0.0)
        self.label = self._simulate() if self.label_mode == "simulate" else self._hydrostatic()
        terms = {
            "correct": float(predict == self.label),
            "spill": -float(self.label and not predict),
        }
        reward, weighted = self._reward(terms)
        info = self._info(weighted, label=self.label, predicted=predict)
        return self._observation(), reward, True, False, info

    def _hydrostatic(self) -> bool:
        volume = self.count * self.fluid_config.particle_volume
        geometry = self.episode_asset.geometry
        return volume > mouth_volume(geometry, self.rotation, self._voxels[self.name])

    def _simulate(self) -> bool:
        container = self._place({"container": self.name})["container"]
        world = self.world
        world.teleport(container, np.zeros(3))
        world.add_particles(container.to_world(self.rest))
        world.step(0.5)  # settle
        # Tilted in steps of 0.1 s: the fluid follows each smoothly in its own substeps.
        steps = round(TILT_TIME / 0.1)
        for k in range(steps + round(HOLD_TIME / 0.1)):
            angle = self.tilt * min((k + 1) / steps, 1.0)
            rot = from_rotvec(np.radians(angle) * AXIS)
            world.set_pose(container, np.zeros(3), rot)
            world.step(0.1)
        self._world_ready = True
        return world.census().elsewhere >= 2

    def _show_scene(self) -> None:
        """The container at the episode's angle, its rest fill rotated along.

        Until a simulated label has put its own fluid there.
        """
        if not self._world_ready:
            container = self._place({"container": self.name})["container"]
            self.world.teleport(container, np.zeros(3), self.rotation)
            self.world.add_particles(self.rest @ self.rotation.T)
            self._world_ready = True

    def _vector_space(self, mode: str) -> spaces.Box:
        if mode == "features":
            return spaces.Box(0.0, 1.0, (1,), np.float32)
        return spaces.Box(-STATE_LIMIT, STATE_LIMIT, (5,), np.float32)

    def _vector_observation(self, mode: str) -> np.ndarray:
        if mode == "features":
            obs = np.array([self.f4])
        else:
            size = np.ptp(self.episode_asset.surface.bounds, axis=0) / 0.1
            obs = np.array([np.radians(self.tilt), self.fill, *size])
        space = self.obs_spaces[mode]
        return np.clip(obs, space.low, space.high).astype(np.float32)

    def _info(self, terms: dict | None = None, **outcome) -> dict:
        """The episode's info; after the step also the reward's terms and the outcome."""
        info = {
            "container": self.name,
            "liquid": self.liquid.name,
            "fill": self.fill,
            "tilt_deg": self.tilt,
            "particles": self.count,
            "features": [self.f4],
            **(terms or {}),
            **outcome,
        }
        info["is_success"] = bool(outcome) and outcome["predicted"] == outcome["label"]
        return info
