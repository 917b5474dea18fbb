"""Gymnasium environments of pour-gym, installed as ``pour_gym.envs``.

``import pour_gym`` registers them under the ``PourGym/`` namespace::

    import gymnasium as gym
    import pour_gym  # noqa: F401
    env = gym.make("PourGym/Pour-v0", objects="train")

The environments are listed once, in :mod:`pour_gym.envs.registry` (``ENVS``; ``ENV_IDS``
their ids, and a constant per id). Each names its :class:`~pour_gym.envs.task.Task`
(``task_of``): what an episode is and how it is scored.
"""

from pour_gym.envs.registry import (
    ENV_IDS,
    ENVS,
    PANDA_POUR_V0,
    PARTICLE_DROP_V0,
    POUR_V0,
    POUR_V1,
    POUR_V2,
    POUR_V3,
    POUR_V4,
    POUR_V5,
    TILT_POUR_V0,
    EnvEntry,
    entry,
    make,
    register_envs,
    task_of,
)
from pour_gym.envs.task import DROP, POUR, TILT, Task, mean_metrics

__all__ = [
    "DROP",
    "ENVS",
    "ENV_IDS",
    "PANDA_POUR_V0",
    "PARTICLE_DROP_V0",
    "POUR",
    "POUR_V0",
    "POUR_V1",
    "POUR_V2",
    "POUR_V3",
    "POUR_V4",
    "POUR_V5",
    "TILT",
    "TILT_POUR_V0",
    "EnvEntry",
    "Task",
    "entry",
    "make",
    "mean_metrics",
    "register_envs",
    "task_of",
]

register_envs()
