"""The one list of pour-gym's environments: ids, entry points, episode lengths, arguments.

Adding an environment is adding an :class:`EnvEntry` to :data:`ENVS`: ``import pour_gym``
registers it with Gymnasium, and the generic tests (API checks, determinism, pickling,
bad actions, the soak) run over every entry with its ``quick`` arguments.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import gymnasium as gym
from gymnasium.envs.registration import load_env_creator, register, registry

from pour_gym.errors import InputError

if TYPE_CHECKING:
    from pour_gym.envs.task import Task

NAMESPACE = "PourGym"
POUR_V0 = "PourGym/Pour-v0"
POUR_V1 = "PourGym/Pour-v1"
POUR_V2 = "PourGym/Pour-v2"
POUR_V3 = "PourGym/Pour-v3"
POUR_V4 = "PourGym/Pour-v4"
POUR_V5 = "PourGym/Pour-v5"
PANDA_POUR_V0 = "PourGym/PandaPour-v0"
PARTICLE_DROP_V0 = "PourGym/ParticleDrop-v0"
TILT_POUR_V0 = "PourGym/TiltPour-v0"
# Small fluids for a pouring episode that takes seconds, not minutes.
_QUICK_POUR = {"source_particles": 300, "amount_range": (40, 80)}
# Pour-v1: Pour-v0's class with defaults a learner can learn from the reward (the class's
# Version History says why each).
POUR_V1_DEFAULTS = {
    "tilt_control": "angle",
    "aim_weight": 0.2,
    "upright_weight": 0.5,
    "success_weight": 2.0,
    "overshoot_weight": 1.0,
}
# Pour-v2: Pour-v1 with a slower tilt (the class's Version History says why).
POUR_V2_DEFAULTS = {**POUR_V1_DEFAULTS, "max_tilt_rate": 20.0}
# Pour-v3: Pour-v2 tilting back at Pour-v1's 60 deg/s (the class's Version History says why).
POUR_V3_DEFAULTS = {**POUR_V2_DEFAULTS, "max_untilt_rate": 60.0}
# Pour-v4: Pour-v3 standing the source up once it has poured, for a tilt named below half
# its onset (the class's Version History says why).
POUR_V4_DEFAULTS = {**POUR_V3_DEFAULTS, "stand_below": 0.5}
# Pour-v5: Pour-v4 with the tilt action naming a stream that the env's regulator holds
# (the class's Version History says why).
POUR_V5_DEFAULTS = {
    **POUR_V4_DEFAULTS,
    "tilt_control": "flow",
    "stand_below": None,
    "observe_flow": True,
}


@dataclass(frozen=True)
class EnvEntry:
    """One registered environment.

    Attributes:
        id: the Gymnasium id, ``PourGym/<Name>-v<N>``.
        entry_point: ``"module:Class"``.
        max_episode_steps: truncation (Gymnasium's ``TimeLimit``).
        kwargs: the id's defaults for the entry point's arguments (e.g. the holder of the
            source, Pour-v1's reward weights); ``gym.make`` arguments override them.
        quick: arguments for a short episode (small fluids): what tests, examples and
            smoke runs pass.
        doc: ``"module:name"`` of the class whose docstring documents the id (its docs
            page); default: the entry point's.
    """

    id: str
    entry_point: str
    max_episode_steps: int
    kwargs: dict = field(default_factory=dict)
    quick: dict = field(default_factory=dict)
    doc: str = ""

    @property
    def slug(self) -> str:
        """The id's file name stem: ``pour-v0`` for ``PourGym/Pour-v0``."""
        return self.id.split("/")[-1].lower()


ENVS: tuple[EnvEntry, ...] = (
    EnvEntry(POUR_V0, "pour_gym.envs.pour:PourEnv", 250, quick=_QUICK_POUR),
    EnvEntry(
        POUR_V1, "pour_gym.envs.pour:PourEnv", 250, kwargs=POUR_V1_DEFAULTS, quick=_QUICK_POUR
    ),
    EnvEntry(
        POUR_V2, "pour_gym.envs.pour:PourEnv", 250, kwargs=POUR_V2_DEFAULTS, quick=_QUICK_POUR
    ),
    EnvEntry(
        POUR_V3, "pour_gym.envs.pour:PourEnv", 250, kwargs=POUR_V3_DEFAULTS, quick=_QUICK_POUR
    ),
    EnvEntry(
        POUR_V4, "pour_gym.envs.pour:PourEnv", 250, kwargs=POUR_V4_DEFAULTS, quick=_QUICK_POUR
    ),
    EnvEntry(
        POUR_V5, "pour_gym.envs.pour:PourEnv", 250, kwargs=POUR_V5_DEFAULTS, quick=_QUICK_POUR
    ),
    EnvEntry(PARTICLE_DROP_V0, "pour_gym.envs.particle_drop:ParticleDropEnv", 1),
    EnvEntry(TILT_POUR_V0, "pour_gym.envs.tilt_pour:TiltPourEnv", 1),
    EnvEntry(
        PANDA_POUR_V0,
        "pour_gym.envs.pour:PourEnv",
        250,
        kwargs={"holder": "panda"},
        quick=_QUICK_POUR,
        doc="pour_gym.envs.holders:PandaHolder",
    ),
)
ENV_IDS: tuple[str, ...] = tuple(e.id for e in ENVS)


def vector_creator_name(env_id: str) -> str:
    """The name of an id's vector env maker in :mod:`pour_gym.envs.vector` (``vector_pour_v1``).

    Registered as ``"pour_gym.envs.vector:<name>"``: a string, so that an env's spec
    stays serialisable (Minari writes it into its datasets).
    """
    return "vector_" + env_id.split("/")[-1].lower().replace("-", "_")


def register_envs() -> None:
    """Register every entry of :data:`ENVS` with Gymnasium (once).

    Each id's ``vector_entry_point`` is the native vector env
    (:class:`~pour_gym.envs.vector.PourVectorEnv`): ``gym.make_vec(id, num_envs=N)``
    steps N envs in threads of this process.
    """
    for e in ENVS:
        if e.id not in registry:
            register(
                id=e.id,
                entry_point=e.entry_point,
                vector_entry_point=f"pour_gym.envs.vector:{vector_creator_name(e.id)}",
                max_episode_steps=e.max_episode_steps,
                kwargs=dict(e.kwargs),
            )
    # Gymnasium calls an id "out of date" whenever a higher version of its name is
    # registered. Pour-v0, v1 and v2 are sets of defaults for one task, all kept on
    # purpose (PourEnv's Version History): the warning would send v0's users to v2 for
    # nothing. Silenced for those ids alone, once (filterwarnings moves a repeated filter
    # to the front instead of adding it again).
    versions = [e.id.rpartition("-v") for e in ENVS]
    for name, _, version in versions:
        if any(n == name and int(v) > int(version) for n, _, v in versions):
            kept = re.escape(f"{name}-v{version}")
            warnings.filterwarnings(
                "ignore", message=rf".*The environment {kept} is out of date",
                category=DeprecationWarning,
            )  # fmt: skip


def entry(env_id: str) -> EnvEntry:
    """The entry of an id (Gymnasium's ``"module:Id"`` form too).

    Raises:
        ValueError: not a pour-gym id; the message lists them.
    """
    name = env_id.split(":")[-1]
    for e in ENVS:
        if e.id == name:
            return e
    raise InputError(f"unknown environment {env_id!r}; pour-gym has {', '.join(ENV_IDS)}")


def task_of(env) -> Task:
    """The :class:`~pour_gym.envs.task.Task` of an environment, its id, or its class.

    Raises:
        ValueError: an id that is not pour-gym's, or an object with no task.
    """
    if isinstance(env, str):
        creator = load_env_creator(entry(env).entry_point)
    else:
        creator = getattr(env, "unwrapped", env)
    task = getattr(creator, "task", None)
    if task is None:
        raise InputError(f"{env!r} is not a pour-gym environment (it has no task)")
    return task


def make(env_id: str, **kwargs) -> gym.Env:
    """``gymnasium.make`` with pour-gym's ids registered first.

    A vector env's worker process, or a Ray worker, unpickles this function (a
    ``functools.partial`` of it) by importing this module, which registers the ids: a
    worker never meets ``NamespaceNotFound``.
    """
    register_envs()
    return gym.make(env_id, **kwargs)
