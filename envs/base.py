"""What the pour-gym environments share: containers, the world, actions, rewards, pictures.

Each environment owns one :class:`~pour_gym.sim.World` (its own pybullet client), built at
the first reset and reused; containers are loaded once per environment (labelled asset and
signed-distance field) and swapped in and out of the world as episodes ask for them. An
environment pickles as its constructor arguments (Gymnasium's ``EzPickle``) and is rebuilt
on arrival.
"""

from __future__ import annotations

import dataclasses
import numbers
from pathlib import Path
from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle

from pour_gym.assets import (
    LabelledAsset,
    check_open,
    expand_containers,
    parse_container,
    resolve_asset,
)
from pour_gym.envs.containers import ContainerStore, release
from pour_gym.envs.observations import VECTOR_MODES, parse_obs_mode
from pour_gym.errors import InputError
from pour_gym.fluid import precompile
from pour_gym.fluid.liquid import Liquid, LiquidRange, liquids_of
from pour_gym.fluid.pbf import PBFConfig, default_threads
from pour_gym.fluid.sdf import SignedDistanceField
from pour_gym.perception import PERCEPTIONS, perceived_asset
from pour_gym.sim import Camera, Container, World
from pour_gym.sim.raster import DRAWN_RADIUS
from pour_gym.sim.sensors import SEGMENTS, Body, Sensor, SensorConfig
from pour_gym.sim.world import CUP_COLORS, FLUIDS, TABLE_COLOR, container_field

RENDER_MODES = ["rgb_array", "human"]
# The particle spacings an env takes, m: finer is slower (a step costs 3.9x at 3.5 mm, 16x
# at 2.5 mm), and at 8 mm a deep column settles 10 % short and a full cup pours 10 deg late
# (`pour-gym bench accuracy --spacing`, docs/liquids.md).
SPACING_RANGE = (0.0025, 0.007)
# Which colour each role's container is drawn in.
ROLE_COLORS = {"source": CUP_COLORS[0], "target": CUP_COLORS[1], "container": CUP_COLORS[1]}


def fluid_config_at(fluid_config: PBFConfig | dict | None, spacing: float | None) -> PBFConfig:
    """The fluid's parameters: ``fluid_config`` (or the defaults) at ``spacing`` (m).

    Raises:
        InputError: a spacing outside :data:`SPACING_RANGE`, or one that contradicts
            ``fluid_config``'s own.
    """
    if isinstance(fluid_config, dict):
        own = fluid_config.get("spacing")
        fluid_config = PBFConfig(**fluid_config)
    else:  # a PBFConfig's default cannot be told from 5 mm set: only another spacing counts
        own = getattr(fluid_config, "spacing", PBFConfig.spacing)
        own = None if own == PBFConfig.spacing else own
    config = fluid_config or PBFConfig()
    if spacing is None:
        return config
    lo, hi = SPACING_RANGE
    if not (isinstance(spacing, numbers.Real) and lo <= spacing <= hi):
        raise InputError(
            f"spacing is the particles' rest distance in m, from {lo} (fine, slow) to {hi} "
            f"(coarse, fast; the default 0.005), not {spacing!r}"
        )
    if own is not None and own != spacing:
        raise InputError(f"spacing={spacing} and fluid_config's spacing {own} differ: give one")
    return dataclasses.replace(config, spacing=float(spacing))


class PourGymEnv(gym.Env, EzPickle):
    """Base class: container specs, a lazily built world, checked actions, rewards, pictures.

    Args:
        fluid: ``"pbf"`` or ``"bullet"``.
        fluid_config: fluid parameters (a :class:`~pour_gym.fluid.pbf.PBFConfig` or a dict).
        num_threads: threads of the PBF fluid; ``None`` picks one per core in a main
            process and one in a worker process (see
            :func:`pour_gym.fluid.pbf.default_threads`).
        render_mode: ``"rgb_array"``, ``"human"`` or None.
        camera: where pictures are taken from.
        reward_weights: the weight of each reward term; a subclass's ``reward_<term>``
            entries in ``info`` are the weighted terms, and they sum to the reward.
        steps_fluid: whether the env steps the fluid (its kernel's compile starts early).
        perception: where the observation's container geometry comes from: ``"true"``
            (the labelled asset) or ``"scan"`` (:mod:`pour_gym.perception`: scanned,
            reconstructed and labelled by warping; the physics keeps the true mesh).
        scan_seed: the scan's noise seed under ``perception="scan"``.
        sensor_config: the head camera's image size, points, noise (a
            :class:`~pour_gym.sim.sensors.SensorConfig` or a dict of its fields), for the
            ``depth``, ``rgb`` and ``points`` observation modes.
        liquid: what is poured (:mod:`pour_gym.fluid.liquid`): a preset's name (``water``,
            ``milk``, ``oil``, ``syrup``, ``honey``), a ``Liquid``, a dict of its fields,
            a range (``{"viscosity": [2, 10], "density": 1400}``: Pa s drawn log-uniformly
            per episode), or a list of them (or ``"water,honey"``) to draw each episode's
            from, seeded; None for water. ``info["liquid"]`` names the episode's.
        spacing: the fluid's particle spacing, m (:data:`SPACING_RANGE`; None: 5 mm, or
            ``fluid_config``'s): coarser for speed, finer for accuracy.
    """

    metadata: ClassVar[dict] = {"render_modes": RENDER_MODES, "render_fps": 10}
    # Whether the world's containers get collision shapes (for an arm that touches them).
    solid: ClassVar[bool] = False
    # Where the sensors' head camera stands (a robot's, looking down at the table), and
    # which segment each role's container is in a point cloud.
    head_camera: ClassVar[Camera] = Camera(
        target=(0.0, 0.0, 0.08), distance=0.4, yaw=0.0, pitch=-40.0, fov=45.0, near=0.1, far=1.0
    )
    role_segments: ClassVar[dict[str, int]] = {
        "source": SEGMENTS["source"],
        "target": SEGMENTS["target"],
        "container": SEGMENTS["target"],
    }

    def __init__(
        self,
        fluid: str,
        fluid_config: PBFConfig | dict | None,
        num_threads: int | None,
        render_mode: str | None,
        camera: Camera,
        reward_weights: dict[str, float],
        steps_fluid: bool = True,
        perception: str = "true",
        scan_seed: int = 0,
        sensor_config: SensorConfig | dict | None = None,
        liquid: str | Liquid | dict | list | None = None,
        spacing: float | None = None,
    ):
        if fluid not in FLUIDS:
            raise InputError(f"fluid must be one of {FLUIDS}, not {fluid!r}")
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise InputError(f"render_mode must be one of {RENDER_MODES} or None")
        if num_threads is not None and int(num_threads) < 1:
            raise InputError(f"num_threads must be at least 1 (or None), not {num_threads}")
        if perception not in PERCEPTIONS:
            raise InputError(f"perception must be one of {PERCEPTIONS}, not {perception!r}")
        fluid_config = fluid_config_at(fluid_config, spacing)
        self.reward_weights: dict[str, float] = {}
        self._add_reward_weights(reward_weights)
        self.fluid = fluid
        self.fluid_config = fluid_config or PBFConfig()
        # Each liquid's fluid parameters, made now: a liquid the fluid cannot take (a spacing
        # with no calibration, rigid spheres) is refused before any work.
        self.liquids = liquids_of(liquid)
        # A range's configs are made as its liquids are drawn; its ends are checked now.
        self._liquid_configs = [
            x.fluid_config(self.fluid_config) if isinstance(x, Liquid) else None
            for x in self.liquids
        ]
        checked = [c for c in self._liquid_configs if c is not None] + [
            end.fluid_config(self.fluid_config)
            for x in self.liquids if isinstance(x, LiquidRange) for end in x.ends()
        ]  # fmt: skip
        if fluid != "pbf" and any(c != self.fluid_config for c in checked):
            raise InputError("liquids other than water need fluid='pbf' (rigid spheres have no "
                             "viscosity)")  # fmt: skip
        first = self.liquids[0]
        self.liquid: Liquid = first if isinstance(first, Liquid) else first.ends()[0]
        self.num_threads = None if num_threads is None else int(num_threads)
        self.render_mode = render_mode
        self.camera = camera
        self._world: World | None = None
        self.perception = perception
        self.scan_seed = int(scan_seed)
        # The containers' assets, fields and drawn meshes, for the containers used last (a
        # vector env gives its envs one store: share_containers).
        self._store = ContainerStore()
        self._placed: dict[str, Container] = {}
        self._names: dict[str, str] = {}  # role -> the container's spec, as given
        self._viewer = None
        self._closed = False
        self._started = False
        self.sensor_config = SensorConfig.of(sensor_config)
        self._sensor: Sensor | None = None
        self._renderer: tuple[Camera, Sensor] | None = None  # render()'s, at ``camera``
        self._sensor_rng: np.random.Generator | None = None
        self.obs_modes: tuple[str, ...] = ()
        self.obs_spaces: dict[str, spaces.Box] = {}
        if steps_fluid and fluid == "pbf":
            # The fluid kernel's compile starts now, in helper processes, if it is not
            # cached: it overlaps loading the containers and the first reset.
            threads = default_threads() if num_threads is None else int(num_threads)
            precompile.start(parallel=threads > 1)

    # ------------------------------------------------------------------ arguments
    def _add_reward_weights(self, weights: dict[str, float]) -> None:
        """Take reward terms' weights (a subclass adds its own terms' this way).

        Raises:
            ValueError: a weight is not a finite number.
        """
        bad = {k: w for k, w in weights.items() if not np.isfinite(w)}
        if bad:
            raise InputError(f"reward weights must be finite numbers, got {bad}")
        self.reward_weights.update({k: float(w) for k, w in weights.items()})

    def _setup_observations(self, obs_mode) -> None:
        """Set ``obs_mode``, ``obs_modes`` and the observation space (a ``Dict`` for several).

        Call it once the subclass can answer :meth:`_vector_space`.
        """
        self.obs_modes = parse_obs_mode(obs_mode)
        self.obs_mode = obs_mode if isinstance(obs_mode, str) else self.obs_modes
        parts = {
            m: self._vector_space(m) if m in VECTOR_MODES else self.sensor_config.space(m)
            for m in self.obs_modes
        }
        # Each mode's space, made once: a vector observation is clipped to it every step.
        self.obs_spaces: dict[str, spaces.Box] = parts
        if len(parts) == 1:
            self.observation_space = parts[self.obs_modes[0]]
        else:
            self.observation_space = spaces.Dict(parts)

    def _vector_space(self, mode: str) -> spaces.Box:
        """The space of a vector mode (``"features"`` or ``"state"``); subclasses say."""
        raise NotImplementedError

    def _vector_observation(self, mode: str) -> np.ndarray:
        """The observation of a vector mode, float32 within its space; subclasses say."""
        raise NotImplementedError

    @staticmethod
    def _options(options: dict | None, allowed: set[str]) -> dict:
        """``reset`` options as a dict; ValueError naming any key not in ``allowed``."""
        options = dict(options or {})
        unknown = set(options) - allowed
        if unknown:
            raise InputError(
                f"unknown reset options {sorted(unknown)}; this environment takes {sorted(allowed)}"
            )
        return options

    # ------------------------------------------------------------------ containers
    def _containers(self, spec) -> tuple[str, ...]:
        """Container names or paths of a split, a name, a path or a list (ValueError if bad).

        A user's container (a mesh file or an asset directory) is loaded here, so that one
        with no opening is refused at construction (:func:`pour_gym.assets.check_open`),
        however it was labelled; the catalogue's and the procedural family's are made open
        (a family's members are labelled when an episode first uses them, or ahead by
        ``pour-gym build-assets``).
        """
        names = expand_containers(spec)
        for name in names:
            if parse_container(name).kind not in ("catalogue", "member"):
                self.asset(name)
        return names

    def share_containers(self, store: ContainerStore) -> None:
        """Keep the containers' loaded data in ``store``, shared with other environments.

        A native vector env gives its envs one store, so that a container is loaded once
        per process. Takes what this environment has loaded so far along.
        """
        store.adopt(self._store)
        self._store = store

    def _choose(self, pool: tuple[str, ...], fixed: str | Path | None) -> str:
        """A container from the pool (``self.np_random``), or the one fixed by options."""
        if fixed is not None:
            return self._containers(fixed)[0]
        return pool[int(self.np_random.integers(len(pool)))]

    def asset(self, name: str) -> LabelledAsset:
        """The labelled asset of a container (kept while it is among those used last)."""
        return self._store.get(name, "asset", lambda: check_open(resolve_asset(name), name))

    def seen(self, name: str) -> LabelledAsset:
        """The container as the observation knows it.

        The labelled asset itself, or (with ``perception="scan"``) what a scan of it gave:
        the reconstruction, labelled by warping (computed once, then cached on disk).

        Raises:
            PerceptionError: a container the perception pipeline cannot take (named).
        """
        if self.perception == "true":
            return self.asset(name)
        return self._store.get(
            name, "seen", lambda: perceived_asset(self.asset(name), self.scan_seed)
        )

    def perceive_all(self, names) -> None:
        """With ``perception="scan"``, perceive every container of ``names`` now.

        So that one the pipeline cannot take is refused here, not at some reset in the
        middle of a run. The first time takes 10-30 s a container: a bar shows it (after 2
        s, so that perceptions read from the cache show nothing).
        """
        if self.perception == "true":
            return
        from tqdm.auto import tqdm

        names = list(dict.fromkeys(names))
        for name in tqdm(names, desc="perceiving containers", unit="container", delay=2.0):
            self.seen(name)

    def _load(self, name: str) -> tuple[LabelledAsset, SignedDistanceField]:
        """The asset and its signed-distance field (computed once, then from the disk cache)."""
        asset = self.asset(name)
        return asset, self._store.get(name, "field", lambda: container_field(asset))

    @property
    def world(self) -> World:
        """The environment's world (built at first use)."""
        if self._closed:
            raise RuntimeError(
                f"this {type(self).__name__} was closed; make a new environment to go on"
            )
        if self._world is None:
            self._world = World(
                self.fluid, self.fluid_config, num_threads=self.num_threads, solid=self.solid
            )
        return self._world

    def _place(self, roles: dict[str, str]) -> dict[str, Container]:
        """Make the world hold exactly these containers, by role (e.g. source, target).

        Containers already in the world under the same role and name are kept (only
        moved later), so that episodes on the same containers cost no reloading.
        """
        world = self.world
        world.clear_particles()
        for role in list(self._placed):
            if roles.get(role) != self._names.get(role):
                world.remove_container(self._placed.pop(role))
                self._names.pop(role, None)
        for role, name in roles.items():
            if role in self._placed:
                continue
            asset, sdf = self._load(name)
            self._placed[role] = world.add_container(
                asset, (0.0, 0.0, 0.0), color=ROLE_COLORS.get(role), sdf=sdf
            )
            self._names[role] = name
        return self._placed

    # ------------------------------------------------------------------ steps
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Seed the environment's generator (subclasses place the episode's scene)."""
        if self._closed:
            raise RuntimeError(
                f"this {type(self).__name__} was closed; make a new environment to go on"
            )
        super().reset(seed=seed)
        # The episode's liquid: drawn only when there is a choice, so that one liquid
        # leaves the episode's draws (and water's episodes, bit for bit) as they were.
        choice = int(self.np_random.integers(len(self.liquids))) if len(self.liquids) > 1 else 0
        picked, config = self.liquids[choice], self._liquid_configs[choice]
        if isinstance(picked, LiquidRange):
            picked = picked.draw(self.np_random)
            config = picked.fluid_config(self.fluid_config)
        self.liquid = picked
        if self.fluid == "pbf":
            self.world.set_liquid(config)
        if seed is not None or self._sensor_rng is None:
            # The sensors' noise and point sampling have a stream of their own, spawned
            # from the episode seed: with or without sensors, a seed gives the same episodes.
            seeds = self.np_random.bit_generator.seed_seq
            self._sensor_rng = np.random.default_rng(seeds.spawn(1)[0])
        self._started = True
        return None

    def _check_action(self, action) -> np.ndarray:
        """The action as a float array of the space's shape; ValueError if it is not one."""
        if self._closed:
            raise RuntimeError(
                f"step() on a closed {type(self).__name__}; make a new environment to go on"
            )
        if not self._started:
            raise RuntimeError(f"call reset() before step() on {type(self).__name__}")
        shape = self.action_space.shape
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"an action is {shape} numbers, got {action!r}") from None
        if a.size != int(np.prod(shape)):
            raise InputError(f"an action has shape {shape}, got {a.shape}: {a.tolist()}")
        a = a.reshape(shape)
        if not np.isfinite(a).all():
            raise InputError(f"the action contains NaN or infinity: {a.tolist()}")
        if np.any(a < -1.0 - 1e-6) or np.any(a > 1.0 + 1e-6):
            raise InputError(f"actions lie in [-1, 1]; got {a.tolist()}")
        return np.clip(a, -1.0, 1.0)

    def _reward(self, terms: dict[str, float]) -> tuple[float, dict[str, float]]:
        """The reward of unweighted terms: their weighted sum, and the weighted terms.

        Args:
            terms: each reward term's value before weighting, by the names of
                ``reward_weights``.

        Returns:
            ``(reward, {"reward_<term>": weighted value})``; the values sum to the reward.
        """
        weighted = {f"reward_{k}": self.reward_weights[k] * float(v) for k, v in terms.items()}
        return float(sum(weighted.values())), weighted

    # ------------------------------------------------------------------ observations
    def _observation(self):
        """The observation in the env's mode(s): an array, or a dict of them by mode."""
        parts = {}
        frame = None
        for mode in self.obs_modes:
            if mode in VECTOR_MODES:
                parts[mode] = self._vector_observation(mode)
                continue
            if frame is None:
                frame = self.capture(rgb="rgb" in self.obs_modes)
            if mode == "depth":
                parts[mode] = self.sensor.depth_image(frame)
            elif mode == "rgb":
                parts[mode] = frame.rgb
            else:
                pose = None
                if self.sensor_config.points_frame == "source":
                    pose = self._sensor_frame_pose()
                parts[mode] = self.sensor.point_cloud(frame, self._sensor_rng, pose)
        if len(parts) == 1:
            return parts[self.obs_modes[0]]
        return parts

    @property
    def sensor(self) -> Sensor:
        """The head camera (made at first use)."""
        if self._sensor is None:
            self._sensor = Sensor(self.head_camera, self.sensor_config)
        return self._sensor

    def capture(self, rgb: bool = False):
        """What the head camera sees now (a :class:`~pour_gym.sim.sensors.Frame`)."""
        self._show_scene()
        radius = self.sensor_config.splat * self.world.config.spacing
        return self._picture(self.sensor, radius, rgb)

    def scene(self, sensor: Sensor) -> list[Body]:
        """Every body in the world as ``sensor`` draws it, at its current pose.

        The placed containers, then what the env adds (the pouring env's holder: the
        Panda's links). The one list that the sensors and :meth:`render` both draw, so a
        picture shows what an observation sees.
        """
        bodies = [
            Body(
                *self._drawn_mesh(role, sensor),
                rotation=c.rotation,
                translation=c.translation,
                segment=self.role_segments[role],
                color=ROLE_COLORS.get(role, CUP_COLORS[2])[:3],
            )
            for role, c in self._placed.items()
        ]
        return bodies + self._more_drawables(sensor)

    def _picture(self, sensor: Sensor, radius: float, rgb: bool):
        """``sensor``'s frame of :meth:`scene`, the table and the fluid drawn at ``radius`` m."""
        world = self.world
        table = TABLE_COLOR[:3] if world.table else None
        return sensor.capture(
            self.scene(sensor), world.particles, radius, table, self._sensor_rng, rgb=rgb,
            liquid_rgb=self.liquid.color,
        )  # fmt: skip

    def _drawn_mesh(self, role: str, sensor: Sensor) -> tuple[np.ndarray, np.ndarray]:
        """The mesh of a role's container as ``sensor`` draws it (made once per detail)."""
        name = self._names[role]
        kind = f"drawn {sensor.cell:.4g}"  # the head camera's and the pictures' differ
        return self._store.get(name, kind, lambda: sensor.mesh(self.asset(name).mesh))

    def _more_drawables(self, sensor: Sensor) -> list[Body]:
        """What the sensors draw besides the containers (the pouring env: its holder)."""
        return []

    def _show_scene(self) -> None:
        """Make the world show the episode before a picture.

        A subclass that keeps its world empty until asked (as TiltPour's hydrostatic label
        does) fills it here.
        """

    def _sensor_frame_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """``(R, origin)`` of ``points_frame="source"``: the source's (or only) container."""
        role = "source" if "source" in self._placed else "container"
        c = self._placed[role]
        return c.rotation, c.translation

    # ------------------------------------------------------------------ pictures
    def render(self) -> np.ndarray | None:
        """An RGB frame (``rgb_array``), or the frame shown in a window (``human``).

        Drawn from :meth:`scene`, as the sensors draw their frames, from ``camera`` at its
        image size: what a picture shows is what the sensors see (an arm included).
        """
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode=...")
            return None
        self._show_scene()
        sensor = self._render_sensor()
        frame = self._picture(sensor, DRAWN_RADIUS * self.world.config.spacing, rgb=True).rgb
        if self.render_mode == "human":
            self._show(frame)
            return None
        return frame

    def _render_sensor(self) -> Sensor:
        """A noiseless sensor at ``camera`` and its image size (made again if it moves)."""
        if self._renderer is None or self._renderer[0] != self.camera:
            cam = self.camera
            config = SensorConfig(width=cam.width, height=cam.height, fov=cam.fov)
            self._renderer = (cam, Sensor(cam, config))
        return self._renderer[1]

    def _show(self, frame: np.ndarray) -> None:
        import matplotlib.pyplot as plt

        if self._viewer is None:
            plt.ion()
            fig, ax = plt.subplots()
            ax.axis("off")
            self._viewer = (fig, ax.imshow(frame))
        else:
            self._viewer[1].set_data(frame)
        self._viewer[0].canvas.draw_idle()
        plt.pause(1.0 / self.metadata["render_fps"])

    def close(self) -> None:
        """Release the world's pybullet client (safe to call twice)."""
        if self._world is not None:
            self._world.close()
            self._world = None
            self._placed = {}
            self._names = {}
        # The containers' data goes with the env (a shared store stays with the others), so
        # that an env closed but not yet collected holds no meshes or fields.
        self._store = ContainerStore(1)
        release()
        if self._viewer is not None:
            import matplotlib.pyplot as plt

            plt.close(self._viewer[0])
            self._viewer = None
        self._closed = True
