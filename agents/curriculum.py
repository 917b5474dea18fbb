"""Training curricula: episodes that start part of the way through the task.

The task stays the environment's own; a curriculum only changes where some training
episodes start, through the environment's documented reset options. Evaluation always
starts as the environment does.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np


class StartNearTarget(gym.Wrapper):
    """Pour-v0: a share of the episodes start with the lip over the target's opening.

    A learner must first find out that tilting over the target pours into it; from the
    default start 20 cm away it seldom tilts far enough at the right place by chance.
    Episodes that start over the target (``reset(options={"near_target": True})``) let
    it learn the pour, and the others the approach.

    Args:
        env: a Pour-v0 environment (possibly wrapped).
        share: the fraction of episodes that start over the target.
    """

    def __init__(self, env: gym.Env, share: float):
        super().__init__(env)
        if not 0.0 <= share <= 1.0:
            raise ValueError(f"share must lie in [0, 1], not {share}")
        self.share = float(share)
        self._rng = np.random.default_rng()

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset, starting over the target in a ``share`` of the episodes."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        options = dict(options or {})
        if "near_target" not in options:
            options["near_target"] = bool(self._rng.random() < self.share)
        return self.env.reset(seed=seed, options=options)
