"""Demonstrations for off-policy learners on Pour-v0: the scripted policy's episodes.

A learner that must find by chance that pouring a little and stopping earns the success
bonus seldom finds it (see docs/learning.md). The scripted policy
(:mod:`pour_gym.agents.policies.scripted`) does it on every thesis container. This module records
its episodes as transitions, keeps them in the replay buffer beside the learner's own
(:class:`DemoReplayBuffer`: a fixed share of every batch, as in RLPD, Ball et al. 2023)
and starts the actor from them by behaviour cloning (:func:`pretrain_actor`). The
learner's actions still come from its network: the demonstrations only shape what it
learns from.

The recorded actions are in the training env's action form: with ``tilt_control="angle"``
the scripted tilt rate r becomes the angle the env reaches in one step at that rate
(:func:`rate_as_angle`), so the env moves exactly as under the rate action.

A policy cloned from an expert's own episodes has only seen the states the expert keeps
to, and on a cup it never saw it soon leaves them (covariate shift). With ``noise`` the
executed actions are the expert's plus Gaussian noise while the expert's clean action is
kept as the label (DART, Laskey et al. 2017): the episodes wander off the expert's path and
record how it corrects, i.e. its feedback law (tilt back when the flow is too strong) rather
than the one trajectory of the training cup.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.type_aliases import ReplayBufferSamples
from tqdm import tqdm

from pour_gym.agents.policies.rollout import Step, rollout
from pour_gym.agents.policies.scripted import ScriptedPourPolicy
from pour_gym.envs import make, task_of
from pour_gym.envs.actions import tilt_action
from pour_gym.errors import InputError

# The env forms a demonstration records in: the expert's rate as it is, or as the tilt
# it reaches ("flow" names a stream, which a recorded rate does not give).
DEMO_FORMS = ("rate", "angle")


@dataclass
class Demonstrations:
    """Transitions of demonstrated episodes (arrays of one row per step).

    Attributes:
        observations: (n, obs_dim) the observations the actions were taken in.
        actions: (n, act_dim) the actions executed, in [-1, 1] (the transitions' actions).
        rewards: (n,) the rewards.
        next_observations: (n, obs_dim) the observations after the actions.
        terminated: (n,) 1.0 where the episode ended by the task (not by the time limit).
        episodes: the number of episodes.
        successes: the number of them that succeeded.
        expert_actions: (n, act_dim) the expert's own actions in the same observations
            (behaviour cloning's labels); the executed ones when None (no noise).
    """

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    next_observations: np.ndarray
    terminated: np.ndarray
    episodes: int
    successes: int
    expert_actions: np.ndarray | None = None

    @property
    def labels(self) -> np.ndarray:
        """The actions behaviour cloning fits: the expert's, without the injected noise."""
        return self.actions if self.expert_actions is None else self.expert_actions

    def __len__(self) -> int:
        return len(self.rewards)


def rate_as_angle(rate: float, env) -> float:
    """The ``tilt_control="angle"`` action that tilts as the rate action ``rate`` does.

    One step of ``env.dt`` at rate r moves the tilt by r * max_tilt_rate * dt deg; the
    angle action whose goal is that tilt moves it by the same amount (the goal is within
    one step's reach), and the env clips both to [0, max_tilt] alike.

    Args:
        rate: the rate action in [-1, 1].
        env: the Pour-v0 env (unwrapped) before the step: its ``tilt`` (deg),
            ``max_tilt_rate`` (deg/s), ``max_tilt`` (deg) and ``dt`` (s).

    Returns:
        The angle action in [-1, 1].
    """
    goal = env.tilt + float(rate) * env.max_tilt_rate * env.dt
    action = tilt_action(goal, env.max_tilt)
    return float(np.clip(action, -1.0, 1.0))


class NoisyExpert:
    """The scripted policy acting in a Pour env, with Gaussian noise on what it executes.

    It reads the features whatever the env's ``obs_mode`` (``env.observe("features")``),
    and gives its actions in the env's tilt form (:func:`rate_as_angle`). After each call
    :attr:`clean` holds the expert's own action in the same form (DART's label).

    Args:
        env: the Pour env, unwrapped (its state is read at every call).
        expert: arguments of :class:`~pour_gym.agents.policies.scripted.ScriptedPourPolicy`.
        sigma: (4,) standard deviations of the noise, action units.
        rng: the noise's generator.

    Raises:
        InputError: arguments the scripted policy does not take.
    """

    def __init__(self, env, expert: dict | None, sigma: np.ndarray, rng: np.random.Generator):
        try:
            self.policy = ScriptedPourPolicy(**(expert or {}))
        except TypeError as exc:
            raise InputError(f"the demonstrating policy's arguments: {exc}") from None
        if env.tilt_control not in DEMO_FORMS:
            raise InputError(
                f"the scripted expert demonstrates with tilt_control {' or '.join(DEMO_FORMS)}, "
                f"not {env.tilt_control!r}"
            )
        self.env = env
        self.sigma = sigma
        self.rng = rng
        self.clean = np.zeros(4)

    def reset(self) -> None:
        """Forget the episode."""
        self.policy.reset()

    def __call__(self, _obs: np.ndarray) -> np.ndarray:
        """The noisy action (the observation passed in is ignored: the expert reads features)."""
        base = self.env
        clean = np.asarray(self.policy(base.observe("features")), dtype=np.float64).copy()
        action = np.clip(clean + self.sigma * self.rng.standard_normal(4), -1.0, 1.0)
        if base.tilt_control == "angle":
            clean[3] = rate_as_angle(clean[3], base)
            action[3] = rate_as_angle(action[3], base)
        self.clean = clean
        return action.astype(np.float32)


def check_recording(env_id: str, episodes: int, noise: float | tuple[float, ...]) -> np.ndarray:
    """Check what a recording of the expert is asked for; the noise per action dimension.

    Raises:
        InputError: fewer than one episode, a negative or infinite noise, or an env the
            scripted policy cannot pour in.
    """
    if episodes < 1:
        raise InputError(f"a recording needs at least one episode, not {episodes}")
    sigma = np.broadcast_to(np.asarray(noise, dtype=np.float64), (4,))
    if np.any(sigma < 0) or not np.all(np.isfinite(sigma)):
        raise InputError(f"the expert's action noise must be finite and >= 0, not {noise}")
    if not task_of(env_id).pours:
        raise InputError(f"the scripted policy pours from a source into a target, not in {env_id}")
    return sigma


def collect_demonstrations(
    env_id: str,
    env_kwargs: dict,
    episodes: int,
    seed: int,
    wrapper: Callable[[gym.Env], gym.Env] | None = None,
    noise: float | tuple[float, ...] = 0.0,
    expert: dict | None = None,
    progress: bool = True,
) -> Demonstrations:
    """Record the scripted policy's episodes in the env a learner trains in.

    The scripted policy reads the features whatever the env's ``obs_mode``; the
    observations recorded are the env's own, so a state agent's demonstrations hold
    state observations. Episodes start as the training's do: the env is wrapped as the
    recipe wraps its training envs (e.g. the curriculum
    :class:`~pour_gym.agents.training.curriculum.TrainingStarts`, seeded by ``seed``).

    Args:
        env_id: a Pour-v0 id (the scripted policy pours).
        env_kwargs: the training env's arguments (containers, reward weights, tilt control).
        episodes: how many episodes.
        seed: the first episode's reset seed (episode k uses seed + k).
        wrapper: wraps the env as the training's are (the recipe's ``env_wrapper``), or
            None.
        noise: standard deviation of the Gaussian noise added to the executed actions
            (one value, or one per action dimension), in action units; the expert's clean
            actions are kept as :attr:`Demonstrations.expert_actions`.
        expert: arguments of the :class:`~pour_gym.agents.policies.scripted.ScriptedPourPolicy`
            that demonstrates (its defaults if None).
        progress: show a progress bar.

    Returns:
        The transitions of every step of every episode.

    Raises:
        InputError: an env the scripted policy cannot act in, or a negative noise.
    """
    sigma = check_recording(env_id, episodes, noise)
    env = make(env_id, **env_kwargs)
    if wrapper is not None:
        env = wrapper(env)
    try:
        expert_policy = NoisyExpert(env.unwrapped, expert, sigma, np.random.default_rng(seed))
    except InputError:
        env.close()
        raise
    rows: dict[str, list] = {k: [] for k in ("obs", "act", "expert", "rew", "next", "term")}
    successes = 0
    bar = tqdm(total=episodes, desc="demonstrations", file=sys.stderr, disable=not progress)

    def record(step: Step) -> None:
        rows["obs"].append(step.obs)
        rows["act"].append(step.action)
        rows["expert"].append(expert_policy.clean)
        rows["rew"].append(step.reward)
        rows["next"].append(step.next_obs)
        rows["term"].append(float(step.terminated))

    for k in range(episodes):
        episode = rollout(env, expert_policy, seed=seed + k, on_step=record)
        successes += bool(episode.info["is_success"])
        bar.update(1)
        bar.set_postfix(success=f"{successes}/{k + 1}")
    bar.close()
    env.close()
    return Demonstrations(
        observations=np.asarray(rows["obs"], dtype=np.float32),
        actions=np.asarray(rows["act"], dtype=np.float32),
        rewards=np.asarray(rows["rew"], dtype=np.float32),
        next_observations=np.asarray(rows["next"], dtype=np.float32),
        terminated=np.asarray(rows["term"], dtype=np.float32),
        episodes=episodes,
        successes=successes,
        expert_actions=np.asarray(rows["expert"], dtype=np.float32) if sigma.any() else None,
    )


class DemoReplayBuffer(ReplayBuffer):
    """SB3's replay buffer with demonstrations kept beside it, never overwritten.

    Every sampled batch takes ``demo_share`` of its transitions from the demonstrations
    (all of them while the learner's own part is empty) and the rest from the learner's
    experience, both normalised by the same ``VecNormalize``. Pass it to an off-policy
    algorithm as ``replay_buffer_class`` (``replay_buffer_kwargs={"demo_share": s}``), then
    :meth:`add_demonstrations`.

    Args:
        demo_share: the share of every batch taken from the demonstrations, in [0, 1].
        *args, **kwargs: SB3's ``ReplayBuffer`` arguments.
    """

    def __init__(self, *args, demo_share: float = 0.5, **kwargs):
        super().__init__(*args, **kwargs)
        if not 0.0 <= demo_share <= 1.0:
            raise ValueError(f"demo_share must lie in [0, 1], not {demo_share}")
        self.demo_share = float(demo_share)
        self.demonstrations: Demonstrations | None = None

    def add_demonstrations(self, demos: Demonstrations) -> None:
        """Keep these demonstrations (replacing any kept before)."""
        self.demonstrations = demos

    def sample(self, batch_size: int, env=None) -> ReplayBufferSamples:
        """A batch: ``demo_share`` demonstrations, the rest the learner's own transitions."""
        demos = self.demonstrations
        if demos is None or len(demos) == 0:
            return super().sample(batch_size, env=env)
        n_demo = batch_size if self.size() == 0 else round(self.demo_share * batch_size)
        # The global generator, as SB3's own sampling: the algorithm's seed fixes it.
        idx = np.random.randint(0, len(demos), size=n_demo)  # noqa: NPY002
        parts = [
            (
                self._normalize_obs(demos.observations[idx], env),
                demos.actions[idx],
                self._normalize_obs(demos.next_observations[idx], env),
                demos.terminated[idx].reshape(-1, 1),
                self._normalize_reward(demos.rewards[idx].reshape(-1, 1), env),
            )
        ]
        if batch_size > n_demo:
            own = super().sample(batch_size - n_demo, env=env)
            parts.append(tuple(t.cpu().numpy() for t in own[:5]))
        data = (np.concatenate([p[k] for p in parts]).astype(np.float32) for k in range(5))
        return ReplayBufferSamples(*tuple(map(self.to_torch, data)))


def _demo_tensors(demos: Demonstrations, normaliser=None) -> tuple[torch.Tensor, torch.Tensor]:
    """The demonstrations' observations (normalised) and actions as tensors."""
    obs = demos.observations
    if normaliser is not None:
        obs = normaliser.normalize_obs(obs)
    # tanh reaches +-1 only at infinity: the log-likelihood needs actions inside.
    actions = np.clip(demos.labels, -0.995, 0.995)
    return torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(actions, dtype=torch.float32)


def _negative_log_likelihood(actor, obs: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
    """Mean negative log-likelihood of actions under an SB3 actor's squashed Gaussian."""
    mean, log_std, kwargs = actor.get_action_dist_params(obs)
    dist = actor.action_dist.proba_distribution(mean, log_std, **kwargs)
    return -dist.log_prob(actions).mean()


def pretrain_actor(
    model,
    demos: Demonstrations,
    normaliser=None,
    steps: int = 2000,
    batch_size: int = 256,
    callback=None,
    every: int = 0,
) -> float:
    """Behaviour cloning: fit an SB3 SAC/TQC actor to the demonstrations' actions.

    Maximises the log-likelihood of the demonstrated actions under the actor's squashed
    Gaussian (mean and spread both fitted), with the actor's own optimiser.

    Args:
        model: a SAC or TQC model (``model.actor``).
        demos: the demonstrations.
        normaliser: the ``VecNormalize`` the learner sees observations through, or None.
        steps: gradient steps.
        batch_size: transitions per step.
        callback: called with the number of steps taken so far before the first step and
            every ``every`` steps (a learning curve's points); the actor is in evaluation
            mode meanwhile.
        every: steps between calls of ``callback`` (0: never).

    Returns:
        The mean squared error of the deterministic actions on the demonstrations
        after the pre-training.
    """
    actor = model.actor
    obs_t, act_t = _demo_tensors(demos, normaliser)
    generator = torch.Generator().manual_seed(0)
    for step in range(steps):
        if callback is not None and every > 0 and step % every == 0:
            actor.set_training_mode(False)
            callback(step)
        actor.set_training_mode(True)
        idx = torch.randint(0, len(obs_t), (batch_size,), generator=generator)
        loss = _negative_log_likelihood(actor, obs_t[idx], act_t[idx])
        actor.optimizer.zero_grad()
        loss.backward()
        actor.optimizer.step()
    actor.set_training_mode(False)
    if callback is not None and every > 0:
        callback(steps)
    with torch.no_grad():
        predicted = actor(obs_t, deterministic=True)
    return float(((predicted - act_t) ** 2).mean())


class BCRegularisedAdam(torch.optim.Adam):
    """Adam whose every step also descends a behaviour-cloning loss.

    SB3's SAC and TQC call ``actor.optimizer.step()`` after back-propagating the actor's
    loss; with this optimiser as the actor's, each step first adds the gradient of
    ``regulariser()`` (a behaviour-cloning loss on demonstrations), in the spirit of
    TD3+BC (Fujimoto and Gu 2021). The learner stays near
    what was demonstrated where the critic does not yet know better.
    """

    regulariser = None

    def step(self, closure=None):
        """Add the regulariser's gradient, then take Adam's step."""
        if self.regulariser is not None:
            self.regulariser().backward()
        return super().step(closure)


def regularise_actor(
    model, demos: Demonstrations, normaliser=None, weight: float = 1.0, batch_size: int = 256
) -> None:
    """Give an SB3 SAC/TQC actor a behaviour-cloning term in every update.

    The term is ``weight`` times the negative log-likelihood of a batch of demonstrated
    actions under the actor's squashed Gaussian: it holds both the mean and the spread of
    the actor near what was demonstrated (a term on the mean alone let the spread grow
    until the learner's own episodes rarely succeeded and its deterministic policy drifted
    off the demonstrations). The normaliser's
    statistics must stay fixed (the demonstrations are normalised once, here).

    Args:
        model: a SAC or TQC model.
        demos: the demonstrations.
        normaliser: the ``VecNormalize`` the learner sees observations through, or None.
        weight: the term's weight against the actor's own loss.
        batch_size: demonstrations per update.
    """
    actor = model.actor
    obs_t, act_t = _demo_tensors(demos, normaliser)
    generator = torch.Generator().manual_seed(1)

    def regulariser() -> torch.Tensor:
        idx = torch.randint(0, len(obs_t), (batch_size,), generator=generator)
        return weight * _negative_log_likelihood(actor, obs_t[idx], act_t[idx])

    old = actor.optimizer
    optimizer = BCRegularisedAdam(actor.parameters(), **old.defaults)
    optimizer.load_state_dict(old.state_dict())
    optimizer.regulariser = regulariser
    actor.optimizer = optimizer
