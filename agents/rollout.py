"""One episode of a policy in an environment: the loop every agent, report and test uses.

A policy is anything called with an observation that returns an action: an SB3 model
wrapped by :func:`sb3_policy`, the scripted policy, the proof of concept's policies, a
searched policy. Policies with state across steps also have ``reset()``, called at the start
of every episode (the :class:`Policy` protocol).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Policy(Protocol):
    """Observation -> action, with ``reset()`` at the start of each episode."""

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action for an observation."""
        ...

    def reset(self) -> None:
        """Forget the last episode."""
        ...


@dataclass
class Episode:
    """What one episode gave.

    Attributes:
        info: the last step's info.
        reward: the return (sum of rewards).
        steps: steps taken.
        infos: every step's info (when asked for).
        frames: a picture after the reset and after every step (when asked for).
    """

    info: dict
    reward: float
    steps: int
    infos: list[dict] = field(default_factory=list)
    frames: list[np.ndarray] = field(default_factory=list)


def rollout(
    env,
    policy: Callable[[np.ndarray], np.ndarray],
    seed: int | None = None,
    options: dict | None = None,
    stop: Callable[[dict], bool] | None = None,
    keep_infos: bool = False,
    frames: bool = False,
    progress: Callable[[], None] | None = None,
) -> Episode:
    """Run one episode.

    Args:
        env: a Gymnasium environment.
        policy: observation -> action (its ``reset()`` is called first, if it has one).
        seed: the reset's seed.
        options: the reset's options.
        stop: ends the episode early when it returns true for a step's info.
        keep_infos: keep every step's info.
        frames: keep ``env.render()`` after the reset and after every step.
        progress: called after every step (a progress bar's update).

    Returns:
        The episode.
    """
    obs, info = env.reset(seed=seed, options=options)
    if hasattr(policy, "reset"):
        policy.reset()
    episode = Episode(info=info, reward=0.0, steps=0)
    if frames:
        episode.frames.append(env.render())
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        episode.reward += float(reward)
        episode.steps += 1
        episode.info = info
        if keep_infos:
            episode.infos.append(info)
        if frames:
            episode.frames.append(env.render())
        if progress is not None:
            progress()
        done = terminated or truncated or (stop is not None and stop(info))
    return episode


def sb3_policy(model) -> Callable[[np.ndarray], np.ndarray]:
    """An SB3 model (with its observation normaliser, if it has one) as a deterministic policy.

    Args:
        model: a loaded SB3 algorithm, or a :class:`~pour_gym.agents.training.Run`.
    """
    normalise = getattr(model, "normalise", None)
    predictor = getattr(model, "model", model)

    def act(obs: np.ndarray) -> np.ndarray:
        x = normalise(obs) if normalise is not None else obs
        action, _ = predictor.predict(x, deterministic=True)
        return action

    return act
