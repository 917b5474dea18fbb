"""Training curricula: episodes that start part of the way through the task.

The task stays the environment's own; a curriculum only changes how some training
episodes start, through the environment's documented reset options. Evaluation always
starts as the environment does.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

# The curriculum's draws come from a stream of their own, spawned from the episode seed
# under this key (the env's own draws and its sensors' take other streams of that seed).
STREAM = 0x5C


class TrainingStarts(gym.Wrapper):
    """Pour-v0: training episodes that start over the target, or with less left to hold back.

    Two things a learner seldom finds by chance from the default start:

    - that tilting over the target pours into it: from the default start 20 cm away it
      seldom tilts far enough at the right place. A ``near_target`` share of the episodes
      start with the lip over the target's opening (``reset(options={"near_target":
      True})``), and the others teach the approach.
    - that it must stop: with the default fill (the target amount T plus 100 particles) a
      learner that pours everything earns most of the reward and never sees a success.
      With ``fill_margin=(lo, hi)`` each episode fills T plus a margin drawn uniformly
      from ``lo``-``hi`` particles of 5 mm (``reset(options={"fill_margin": m})``, ``m``
      scaled to the env's spacing so that it holds the same volume): near 0,
      pouring everything and setting the source upright is a success, and because the
      margin varies, only "poured close to T", not "the source is nearly empty", tells
      when to stop.

    Args:
        env: a Pour-v0 environment (possibly wrapped).
        near_target: the fraction of episodes that start over the target.
        fill_margin: (lo, hi) particles of fill beyond T (counted at the default 5 mm
            spacing), or None for the env's own fill.
    """

    def __init__(
        self,
        env: gym.Env,
        near_target: float = 0.0,
        fill_margin: tuple[int, int] | None = None,
    ):
        super().__init__(env)
        if not 0.0 <= near_target <= 1.0:
            raise ValueError(f"near_target must lie in [0, 1], not {near_target}")
        if fill_margin is not None:
            lo, hi = (int(m) for m in fill_margin)
            if not 0 <= lo <= hi:
                raise ValueError(f"fill_margin must be (lo, hi), 0 <= lo <= hi, not {fill_margin}")
            fill_margin = (lo, hi)
        self.near_target = float(near_target)
        self.fill_margin = fill_margin
        self._rng: np.random.Generator | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset, drawing this episode's start (options given by the caller win).

        The draws are reproducible from the env's seed: a seeded reset starts them anew
        from its seed; before the first one, from the seed the env's own generator has
        (random, if the env was never seeded, as its episodes are then).
        """
        if seed is not None or self._rng is None:
            if seed is None:
                seed = self.env.unwrapped.np_random_seed
            self._rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(STREAM,)))
        options = dict(options or {})
        # Both draws are taken every episode, so that one setting does not shift the other's.
        near = bool(self._rng.random() < self.near_target)
        options.setdefault("near_target", near)
        if self.fill_margin is not None:
            margin = int(self._rng.integers(self.fill_margin[0], self.fill_margin[1] + 1))
            # Drawn in 5 mm particles, so a margin holds its volume at any spacing.
            per_5mm = getattr(self.env.unwrapped, "per_5mm", 1.0)
            options.setdefault("fill_margin", round(margin * per_5mm))
        return self.env.reset(seed=seed, options=options)
