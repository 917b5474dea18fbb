"""What the pour-gym environments share: containers, the world, actions, pictures, pickling.

Each environment owns one :class:`~pour_gym.sim.World` (its own pybullet client), built at
the first reset and reused; containers are loaded once per environment (labelled asset and
signed-distance field) and swapped in and out of the world as episodes ask for them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from pour_gym.assets import LabelledAsset, expand_containers, resolve_asset
from pour_gym.fluid.pbf import PBFConfig
from pour_gym.fluid.sdf import SignedDistanceField
from pour_gym.sim import Camera, Container, World
from pour_gym.sim.world import FLUIDS, container_field

RENDER_MODES = ["rgb_array", "human"]
OBS_MODES = ("features", "state")


class PourGymEnv(gym.Env):
    """Base class: container specs, a lazily built world, checked actions, rendering.

    Subclasses set ``self._init_kwargs`` (for pickling) and the spaces, and call
    :meth:`_setup` from their ``__init__``.
    """

    metadata: ClassVar[dict] = {"render_modes": RENDER_MODES, "render_fps": 10}

    def _setup(
        self,
        fluid: str,
        fluid_config: PBFConfig | dict | None,
        render_mode: str | None,
        camera: Camera,
    ) -> None:
        if fluid not in FLUIDS:
            raise ValueError(f"fluid must be one of {FLUIDS}, not {fluid!r}")
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES} or None")
        if isinstance(fluid_config, dict):
            fluid_config = PBFConfig(**fluid_config)
        self.fluid = fluid
        self.fluid_config = fluid_config or PBFConfig()
        self.render_mode = render_mode
        self.camera = camera
        self._world: World | None = None
        self._loaded: dict[str, tuple[LabelledAsset, SignedDistanceField]] = {}
        self._placed: dict[str, Container] = {}
        self._viewer = None

    # ------------------------------------------------------------------ arguments
    @staticmethod
    def _check_obs_mode(obs_mode: str) -> str:
        if obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {OBS_MODES}, not {obs_mode!r}")
        return obs_mode

    @staticmethod
    def _options(options: dict | None, allowed: set[str]) -> dict:
        """``reset`` options as a dict; ValueError naming any key not in ``allowed``."""
        options = dict(options or {})
        unknown = set(options) - allowed
        if unknown:
            raise ValueError(
                f"unknown reset options {sorted(unknown)}; this environment takes {sorted(allowed)}"
            )
        return options

    # ------------------------------------------------------------------ containers
    @staticmethod
    def _containers(spec) -> tuple[str, ...]:
        """Container names or paths of a split, a name, a path or a list (ValueError if bad)."""
        return expand_containers(spec)

    def _choose(self, pool: tuple[str, ...], fixed: str | Path | None) -> str:
        """A container from the pool (``self.np_random``), or the one fixed by options."""
        if fixed is not None:
            return expand_containers(fixed)[0]
        return pool[int(self.np_random.integers(len(pool)))]

    def asset(self, name: str) -> LabelledAsset:
        """The labelled asset of a container (loaded once per environment)."""
        return self._load(name)[0]

    def _load(self, name: str) -> tuple[LabelledAsset, SignedDistanceField]:
        if name not in self._loaded:
            asset = resolve_asset(name)
            self._loaded[name] = (asset, container_field(asset))
        return self._loaded[name]

    @property
    def world(self) -> World:
        """The environment's world (built at first use)."""
        if self._world is None:
            self._world = World(self.fluid, self.fluid_config)
        return self._world

    def _place(self, roles: dict[str, str]) -> dict[str, Container]:
        """Make the world hold exactly these containers, by role (e.g. source, target).

        Containers already in the world under the same role and name are kept (only
        moved later), so that episodes on the same containers cost no reloading.
        """
        world = self.world
        world.clear_particles()
        for role in list(self._placed):
            c = self._placed[role]
            if roles.get(role) != c.asset.meta.get("_spec"):
                world.remove_container(c)
                del self._placed[role]
        colours = {"source": (0.85, 0.2, 0.2, 1.0), "target": (0.92, 0.92, 0.88, 1.0)}
        for role, name in roles.items():
            if role in self._placed:
                continue
            asset, sdf = self._load(name)
            asset.meta["_spec"] = name
            self._placed[role] = world.add_container(
                asset, (0.0, 0.0, 0.0), color=colours.get(role), sdf=sdf
            )
        return self._placed

    # ------------------------------------------------------------------ actions
    def _check_action(self, action) -> np.ndarray:
        """The action as a float array of the space's shape; ValueError if it is not one."""
        a = np.asarray(action, dtype=np.float64).reshape(self.action_space.shape)
        if not np.isfinite(a).all():
            raise ValueError(f"the action contains NaN or infinity: {a.tolist()}")
        if np.any(a < -1.0 - 1e-6) or np.any(a > 1.0 + 1e-6):
            raise ValueError(f"actions lie in [-1, 1]; got {a.tolist()}")
        return a

    # ------------------------------------------------------------------ pictures
    def render(self) -> np.ndarray | None:
        """An RGB frame (``rgb_array``), or the frame shown in a window (``human``)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode=...")
            return None
        frame = self.world.render(self.camera)
        if self.render_mode == "human":
            self._show(frame)
            return None
        return frame

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
        if self._viewer is not None:
            import matplotlib.pyplot as plt

            plt.close(self._viewer[0])
            self._viewer = None

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict[str, Any]:
        # A pybullet client cannot be pickled: an environment travels as its arguments
        # and is rebuilt on arrival (reset it before use, as after gymnasium.make).
        return {"init_kwargs": self._init_kwargs}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(**state["init_kwargs"])
