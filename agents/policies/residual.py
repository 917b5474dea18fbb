"""Residual learning on the scripted expert: a learner that corrects the expert's actions.

The executed action is the scripted expert's
(:class:`~pour_gym.agents.policies.scripted.ScriptedPourPolicy`) plus the learner's action
times a small ``scale``, clipped to the action space. The learner sees the observation
with the expert's proposed action and its phase (move, tilt, back) appended, so that it can
tell what it corrects. A learner whose actions are 0 is the expert;
one trained on the reward keeps what the expert does well and learns what it gets wrong
(where its script stops the pour too late or too early), the usual way to improve on a
hand-written controller with RL (Silver et al. 2018, "Residual Policy Learning"; Johannink
et al. 2019, "Residual Reinforcement Learning for Robot Control").

Training wraps each env in :class:`ExpertResidual` (a recipe's ``residual`` key); a trained
run acts through :class:`ResidualPolicy`, the same arithmetic around a policy, which
:func:`~pour_gym.agents.policies.rollout.sb3_policy` puts in place when the run's config
has the key.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import gymnasium as gym
import numpy as np

from pour_gym.agents.policies.scripted import (
    ACTION_SETTINGS,
    ScriptedPourPolicy,
    action_settings,
)
from pour_gym.errors import InputError

PHASES = ("move", "tilt", "back")  # the expert's phases, appended one-hot


@dataclass(frozen=True)
class ResidualConfig:
    """The ``residual`` key of a recipe.

    Attributes:
        scale: the learner's action is multiplied by this (one value, or one per action
            dimension) before it is added to the expert's: how far it may move the
            expert's action (the tilt action of Pour-v0 while pouring is 0.06 or less).
        expert: arguments of the scripted expert (its action settings come from the env).
    """

    scale: tuple[float, ...] = (0.05, 0.05, 0.05, 0.1)
    expert: dict = field(default_factory=dict)

    @classmethod
    def from_recipe(cls, value: dict) -> ResidualConfig:
        """From a recipe's (or a run's ``config.json``) mapping; InputError on bad keys."""
        unknown = sorted(set(value) - {"scale", "expert"})
        if unknown:
            raise InputError(f"unknown residual keys {unknown}; use scale, expert")
        scale = value.get("scale", cls.scale)
        scale = tuple(float(s) for s in (scale if isinstance(scale, list | tuple) else [scale]))
        if not all(s > 0 for s in scale):
            raise InputError(f"residual scale must be positive, not {list(scale)}")
        expert = dict(value.get("expert") or {})
        known = set(ScriptedPourPolicy.__dataclass_fields__) - set(ACTION_SETTINGS) - {"dt"}
        bad = sorted(set(expert) - known)
        if bad:
            raise InputError(f"unknown expert arguments {bad} in residual; use {sorted(known)}")
        return cls(scale=scale, expert=expert)

    def to_dict(self) -> dict:
        """As a recipe writes it (``config.json``)."""
        return {**asdict(self), "scale": list(self.scale)}


class ResidualCore:
    """The expert and the arithmetic that adds a learner's correction to its action.

    Args:
        config: the residual's scale and expert arguments.
        settings: the env's action form
            (:func:`~pour_gym.agents.policies.scripted.action_settings`).
        action_dim: the env's action dimension.
    """

    def __init__(self, config: ResidualConfig, settings: dict, action_dim: int = 4):
        self.expert = ScriptedPourPolicy(
            **config.expert, **{k: settings[k] for k in ACTION_SETTINGS}
        )
        scale = np.asarray(config.scale, dtype=np.float64)
        if scale.size not in (1, action_dim):
            raise InputError(
                f"residual scale has {scale.size} values; give 1 or {action_dim} (one per action)"
            )
        self.scale = np.broadcast_to(scale, (action_dim,)).copy()
        self.base = np.zeros(action_dim)

    def reset(self) -> None:
        """Start an episode (the expert forgets its phase)."""
        self.expert.reset()

    def observe(self, obs: np.ndarray) -> np.ndarray:
        """The learner's observation: ``obs``, the expert's action for it, its phase one-hot.

        Call once per step, before :meth:`act`: the expert decides here (it keeps state).
        """
        self.base = np.asarray(self.expert(obs), dtype=np.float64)
        phase = np.array([self.expert.phase == p for p in PHASES], dtype=np.float64)
        return np.concatenate([obs, self.base, phase]).astype(np.float32)

    def act(self, residual: np.ndarray) -> np.ndarray:
        """The executed action: the expert's plus the scaled correction, within [-1, 1]."""
        correction = self.scale * np.clip(np.asarray(residual, dtype=np.float64), -1.0, 1.0)
        # Double, as the expert gives it: a correction of 0 is the expert to the last bit.
        return np.clip(self.base + correction, -1.0, 1.0)


def _settings_of(env: gym.Env) -> dict:
    env = env.unwrapped
    if getattr(env, "obs_mode", None) != "features":
        raise InputError(
            "a residual on the scripted expert needs obs_mode='features' (the expert reads "
            f"the warped features), not {getattr(env, 'obs_mode', None)!r}"
        )
    return {mine: getattr(env, theirs) for mine, theirs in ACTION_SETTINGS.items()}


class ExpertResidual(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """A Pour env whose action is a correction to the scripted expert's (training side).

    Observations gain the expert's action (4 values in [-1, 1]) and its phase (3 values,
    one-hot); actions are corrections in [-1, 1], scaled by ``scale``.

    Args:
        env: a Pour env (``obs_mode="features"``), possibly wrapped.
        scale: see :class:`ResidualConfig`.
        expert: see :class:`ResidualConfig`.
    """

    def __init__(self, env: gym.Env, scale=ResidualConfig.scale, expert: dict | None = None):
        # Recorded, so that the env's spec can make it again (Gymnasium's check_env does).
        gym.utils.RecordConstructorArgs.__init__(self, scale=scale, expert=expert)
        super().__init__(env)
        config = ResidualConfig.from_recipe({"scale": scale, "expert": expert or {}})
        self.core = ResidualCore(config, _settings_of(env), env.action_space.shape[0])
        space = env.observation_space
        extra = self.core.base.size + len(PHASES)
        low = np.concatenate([space.low, -np.ones(self.core.base.size), np.zeros(len(PHASES))])
        high = np.concatenate([space.high, np.ones(extra)])
        self.observation_space = gym.spaces.Box(low.astype(np.float32), high.astype(np.float32))
        self.action_space = gym.spaces.Box(-1.0, 1.0, env.action_space.shape, np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset the env and the expert."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.core.reset()
        return self.core.observe(obs), info

    def step(self, action):
        """Step with the expert's action plus the correction."""
        obs, reward, terminated, truncated, info = self.env.step(self.core.act(action))
        return self.core.observe(obs), reward, terminated, truncated, info


class ResidualPolicy:
    """A trained residual learner with its expert, as a policy of the plain env.

    Args:
        learner: the learner as a policy of the augmented observation (its ``reset``,
            with or without a seed, is passed on).
        config: the residual's scale and expert.
        settings: the env's action form
            (:func:`~pour_gym.agents.policies.scripted.action_settings`).
    """

    def __init__(
        self, learner: Callable[[np.ndarray], np.ndarray], config: ResidualConfig, settings: dict
    ):
        self.learner = learner
        self.core = ResidualCore(config, settings)

    def reset(self, seed: int | None = None) -> None:
        """Start an episode (the expert's phase; the learner's noise seed, if it samples)."""
        self.core.reset()
        reset = getattr(self.learner, "reset", None)
        if reset is not None:
            # A learner that samples takes the episode's seed (as rollout gives policies).
            takes_seed = "seed" in inspect.signature(reset).parameters
            reset(seed=seed) if takes_seed else reset()

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action: the expert's plus the learner's correction."""
        return self.core.act(self.learner(self.core.observe(obs)))


def residual_policy(learner: Callable, run_config: dict) -> Callable[[np.ndarray], np.ndarray]:
    """``learner`` as a policy of the plain env if its run learnt a residual, else itself.

    Args:
        learner: the SB3 model as a policy.
        run_config: the run's ``config.json`` (``residual``, ``env``, ``env_kwargs``).
    """
    value = run_config.get("residual")
    if not value:
        return learner
    env_kwargs = run_config.get("env_kwargs") or {}
    if env_kwargs.get("obs_mode", run_config.get("obs_mode", "features")) != "features":
        raise InputError("a residual on the scripted expert needs obs_mode='features'")
    settings = action_settings(run_config["env"], env_kwargs)
    return ResidualPolicy(learner, ResidualConfig.from_recipe(value), settings)
