"""Gymnasium environments of pour-gym, installed as ``pour_gym.envs``.

Environment ids are registered here under the ``PourGym/`` namespace; ``ENV_IDS`` lists
the registered ones. The pouring environments build on the labelled assets and the fluid
world, which later work adds; until then no environment is registered.
"""

ENV_IDS: tuple[str, ...] = ()
