"""One episode of a policy in an environment: the loop every agent, report and test uses.

A policy is anything called with an observation that returns an action: an SB3 model
wrapped by :func:`sb3_policy`, the scripted policy, the proof of concept's policies, a
searched policy. Policies with state across steps also have ``reset()``, called at the start
of every episode (the :class:`Policy` protocol); a policy that samples its actions takes
the episode's seed there (``reset(seed=...)``), so that an episode is the same every time.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from pour_gym.envs.task import Task


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
class Step:
    """One step of an episode, as a rollout's ``on_step`` hook sees it.

    Attributes:
        obs: the observation the action was chosen from.
        action: the action taken.
        reward: the step's reward.
        next_obs: the observation after the step.
        terminated: whether the step ended the episode (Gymnasium's ``terminated``).
        truncated: whether the step cut the episode short (Gymnasium's ``truncated``).
        info: the step's info.
        index: steps taken so far, this one included.
    """

    obs: np.ndarray
    action: np.ndarray
    reward: float
    next_obs: np.ndarray
    terminated: bool
    truncated: bool
    info: dict
    index: int


@dataclass
class Episode:
    """What one episode gave.

    Attributes:
        info: the last step's info.
        reward: the return (sum of rewards).
        steps: steps taken.
        reset_info: the reset's info.
        step_seconds: wall time spent inside ``env.step``, s.
        infos: every step's info (when asked for).
        frames: a picture after the reset and after every step (when asked for).
    """

    info: dict
    reward: float
    steps: int
    reset_info: dict = field(default_factory=dict)
    step_seconds: float = 0.0
    infos: list[dict] = field(default_factory=list)
    frames: list[np.ndarray] = field(default_factory=list)

    def metrics(self, task: Task) -> dict[str, float]:
        """The episode's metrics as its env's task defines them (success, return, ...)."""
        return task.metrics(self.info, self.reward)


def rollout(
    env,
    policy: Callable[[np.ndarray], np.ndarray],
    seed: int | None = None,
    options: dict | None = None,
    on_step: Callable[[Step], bool | None] | None = None,
    keep_infos: bool = False,
    frames: bool = False,
) -> Episode:
    """Run one episode.

    Args:
        env: a Gymnasium environment.
        policy: observation -> action (its ``reset()`` is called first, if it has one).
        seed: the reset's seed.
        options: the reset's options.
        on_step: called after every step with the :class:`Step`; the episode ends early
            when it returns True (a recorder, a progress bar, a check, a stop rule).
        keep_infos: keep every step's info.
        frames: keep ``env.render()`` after the reset and after every step.

    Returns:
        The episode.
    """
    obs, info = env.reset(seed=seed, options=options)
    if hasattr(policy, "reset"):
        if "seed" in inspect.signature(policy.reset).parameters:
            policy.reset(seed=seed)  # a policy that samples: the episode's seed
        else:
            policy.reset()
    episode = Episode(info=info, reward=0.0, steps=0, reset_info=info)
    if frames:
        episode.frames.append(env.render())
    done = False
    while not done:
        action = policy(obs)
        start = time.perf_counter()
        next_obs, reward, terminated, truncated, info = env.step(action)
        episode.step_seconds += time.perf_counter() - start
        episode.reward += float(reward)
        episode.steps += 1
        episode.info = info
        if keep_infos:
            episode.infos.append(info)
        if frames:
            episode.frames.append(env.render())
        stop = False
        if on_step is not None:
            step = Step(obs, action, float(reward), next_obs, terminated, truncated, info,
                        episode.steps)  # fmt: skip
            stop = on_step(step) is True
        obs = next_obs
        done = terminated or truncated or stop
    return episode


def sb3_policy(model, deterministic: bool | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """An SB3 model (with its observation normaliser, if it has one) as a policy.

    Args:
        model: a loaded SB3 algorithm, or a :class:`~pour_gym.agents.training.Run`.
        deterministic: act with the distribution's mean (True) or sample the actions
            (False: the policy that PPO optimises; see :class:`SampledPolicy`). None: as
            the run's config says (``stochastic_eval``), else the mean.

    A run that learnt a correction to the scripted expert (its config's ``residual``)
    acts as :class:`~pour_gym.agents.policies.residual.ResidualPolicy`: the expert plus the model.
    """
    normalise = getattr(model, "normalise", None)
    predictor = getattr(model, "model", model)
    config = getattr(model, "config", {})
    if deterministic is None:
        deterministic = not config.get("stochastic_eval", False)
    from pour_gym.agents.policies.residual import residual_policy

    if not deterministic:
        return residual_policy(SampledPolicy(predictor, normalise), config)

    def act(obs: np.ndarray) -> np.ndarray:
        x = normalise(obs) if normalise is not None else obs
        action, _ = predictor.predict(x, deterministic=True)
        return action

    # A run that learnt a correction to the scripted expert acts with the expert.
    return residual_policy(act, config)


class SampledPolicy:
    """An SB3 policy that samples its actions, from a seed per episode.

    SB3 samples with torch's global generator; each step here draws in a forked copy of
    it, seeded from the episode's generator, so that an episode is the same for the same
    seed and nothing else's random numbers change. A model exploring by gSDE (``use_sde``)
    samples as it did in training: its noise weights drawn at the episode's start and
    every ``sde_sample_freq`` steps (SB3's rollouts), not left at whatever loading drew.

    Args:
        predictor: the SB3 algorithm.
        normalise: the observation normaliser, or None.
    """

    def __init__(self, predictor, normalise: Callable[[np.ndarray], np.ndarray] | None):
        self.predictor = predictor
        self.normalise = normalise
        self.rng = np.random.default_rng(0)
        self.steps = 0
        self.sde_every = (
            getattr(predictor, "sde_sample_freq", -1)
            if getattr(predictor, "use_sde", False)
            else None
        )

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: its actions' noise from ``seed``."""
        self.rng = np.random.default_rng(seed)
        self.steps = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """A sampled action for an observation."""
        import torch

        x = self.normalise(obs) if self.normalise is not None else obs
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(int(self.rng.integers(2**62)))
            every = self.sde_every
            if every is not None and (self.steps == 0 or (every > 0 and self.steps % every == 0)):
                self.predictor.policy.reset_noise(1)
            action, _ = self.predictor.predict(x, deterministic=False)
        self.steps += 1
        return action


class RandomPolicy:
    """Actions drawn uniformly from a box action space, from a seed per episode.

    The reference a normalised score calls 0 (Minari's ``ref_min_score``): the same
    episodes as a policy's evaluation, acted on at random, the same for the same seeds.

    Args:
        low: the action space's lower bounds.
        high: its upper bounds.
    """

    def __init__(self, low: np.ndarray, high: np.ndarray):
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.rng = np.random.default_rng(0)

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: its actions from ``seed``."""
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """A uniform action (the observation is not read)."""
        return self.rng.uniform(self.low, self.high).astype(np.float32)
