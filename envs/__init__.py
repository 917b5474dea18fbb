"""Gymnasium environments of pour-gym, installed as ``pour_gym.envs``.

``import pour_gym`` registers them under the ``PourGym/`` namespace::

    import gymnasium as gym
    import pour_gym  # noqa: F401
    env = gym.make("PourGym/Pour-v0", objects="train")

``ENV_IDS`` lists the registered ids, ``POUR_ENV_IDS`` those of the pouring tasks.
"""

from gymnasium.envs.registration import register, registry

ENV_IDS: tuple[str, ...] = (
    "PourGym/Pour-v0",
    "PourGym/ParticleDrop-v0",
    "PourGym/TiltPour-v0",
    "PourGym/PandaPour-v0",
)
# The pouring tasks (a source poured into a target; their episodes have both).
POUR_ENV_IDS: tuple[str, ...] = ("PourGym/Pour-v0", "PourGym/PandaPour-v0")
_ENTRY_POINTS = {
    "PourGym/Pour-v0": ("pour_gym.envs.pour:PourEnv", 250),
    "PourGym/ParticleDrop-v0": ("pour_gym.envs.particle_drop:ParticleDropEnv", 1),
    "PourGym/TiltPour-v0": ("pour_gym.envs.tilt_pour:TiltPourEnv", 1),
    "PourGym/PandaPour-v0": ("pour_gym.envs.panda_pour:PandaPourEnv", 250),
}

for _id, (_entry, _steps) in _ENTRY_POINTS.items():
    if _id not in registry:
        register(id=_id, entry_point=_entry, max_episode_steps=_steps)
