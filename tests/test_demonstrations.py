"""Demonstrations for off-policy learners: recorded as the env moves, sampled as asked."""

import functools

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium import spaces

import pour_gym  # noqa: F401 - registers the environments
from pour_gym.agents.training.curriculum import TrainingStarts
from pour_gym.agents.training.demonstrations import (
    Demonstrations,
    DemoReplayBuffer,
    collect_demonstrations,
    pretrain_actor,
    rate_as_angle,
    regularise_actor,
)


def _synthetic_demos(n: int, obs_dim: int, act_dim: int, value: float) -> Demonstrations:
    obs = np.full((n, obs_dim), value, dtype=np.float32)
    return Demonstrations(
        observations=obs,
        actions=np.full((n, act_dim), 0.5, dtype=np.float32),
        rewards=np.ones(n, dtype=np.float32),
        next_observations=obs.copy(),
        terminated=np.zeros(n, dtype=np.float32),
        episodes=1,
        successes=1,
    )


def test_rate_as_angle_tilts_the_source_as_the_rate_action_does():
    """The same tilt rates, given as rates to one env and as angles to another, give the same
    tilt after every step (clipped at upright and at max_tilt alike)."""
    kwargs = {"objects": ["red_cup"], "amount_range": (100, 100), "max_tilt": 40.0}
    by_rate = gym.make("PourGym/Pour-v0", **kwargs)
    by_angle = gym.make("PourGym/Pour-v0", tilt_control="angle", **kwargs)
    by_rate.reset(seed=3)
    by_angle.reset(seed=3)
    a, b = by_rate.unwrapped, by_angle.unwrapped
    for rate in (-1.0, 1.0, 1.0, 0.3, 1.0, 1.0, 1.0, 1.0, -0.5, -1.0, -1.0, -1.0, -1.0):
        angle = rate_as_angle(rate, b)
        by_rate.step(np.array([0, 0, 0, rate], dtype=np.float32))
        by_angle.step(np.array([0, 0, 0, angle], dtype=np.float32))
        assert b.tilt == pytest.approx(a.tilt, abs=1e-4)
    assert max(a.tilt, b.tilt) < 40.0 + 1e-9
    by_rate.close()
    by_angle.close()


@pytest.mark.slow
def test_collected_demonstrations_succeed_and_hold_the_env_observations():
    kwargs = {"objects": ["red_cup"], "tilt_control": "angle", "obs_mode": "state"}
    demos = collect_demonstrations("PourGym/Pour-v0", kwargs, 2, seed=7, progress=False)
    assert demos.episodes == 2 and demos.successes == 2
    assert demos.observations.shape == (len(demos), 19)  # the state observation
    assert demos.terminated.sum() == 2 and demos.terminated[-1] == 1.0
    # Each next observation is the following step's observation within an episode.
    ends = np.flatnonzero(demos.terminated)
    assert np.array_equal(demos.next_observations[: ends[0]], demos.observations[1 : ends[0] + 1])
    # Replayed in a fresh env from the same seeds, the recorded actions give the recorded
    # observations, step by step.
    env = gym.make("PourGym/Pour-v0", **kwargs)
    starts = np.concatenate([[0], ends[:-1] + 1])
    for k, (first, last) in enumerate(zip(starts, ends, strict=True)):
        obs, _ = env.reset(seed=7 + k)
        assert np.array_equal(obs, demos.observations[first])
        for i in range(first, last + 1):
            obs, *_ = env.step(demos.actions[i])
            assert np.array_equal(obs, demos.next_observations[i])
    env.close()


def test_replay_batches_take_the_demonstration_share():
    obs_space = spaces.Box(-10, 10, (3,), np.float32)
    act_space = spaces.Box(-1, 1, (2,), np.float32)
    buffer = DemoReplayBuffer(100, obs_space, act_space, n_envs=1, demo_share=0.25)
    buffer.add_demonstrations(_synthetic_demos(20, 3, 2, value=-1.0))
    np.random.seed(0)  # noqa: NPY002 - the buffer samples with the global generator, as SB3
    only_demos = buffer.sample(40)
    assert torch.all(only_demos.observations == -1.0)  # nothing of its own yet
    for _ in range(10):
        buffer.add(
            np.ones((1, 3)), np.ones((1, 3)), np.zeros((1, 2)), np.zeros(1), np.zeros(1), [{}]
        )
    batch = buffer.sample(40)
    assert batch.observations.shape == (40, 3) and batch.rewards.shape == (40, 1)
    assert int((batch.observations[:, 0] == -1.0).sum()) == 10
    assert int((batch.observations[:, 0] == 1.0).sum()) == 30
    with pytest.raises(ValueError, match="demo_share"):
        DemoReplayBuffer(10, obs_space, act_space, demo_share=1.5)


def test_behaviour_cloning_fits_the_actor_and_the_term_holds_it():
    from sb3_contrib import TQC

    torch.manual_seed(0)
    env = gym.make("Pendulum-v1")
    model = TQC("MlpPolicy", env, seed=0, device="cpu", policy_kwargs={"net_arch": [32, 32]})
    rng = np.random.default_rng(0)
    obs = rng.uniform(-1, 1, (512, 3)).astype(np.float32)
    demos = Demonstrations(
        observations=obs,
        actions=np.tanh(obs[:, :1] - obs[:, 1:2]).astype(np.float32),  # a smooth policy
        rewards=np.zeros(512, np.float32),
        next_observations=obs,
        terminated=np.zeros(512, np.float32),
        episodes=1,
        successes=1,
    )
    with torch.no_grad():
        predicted = model.actor(torch.as_tensor(obs), deterministic=True).numpy()
    before = float(((predicted - demos.actions) ** 2).mean())
    after = pretrain_actor(model, demos, steps=400, batch_size=128)
    assert after < 0.01 < before
    # The regularised optimiser pulls a perturbed actor back towards the demonstrations.
    regularise_actor(model, demos, weight=1.0)
    with torch.no_grad():
        for p in model.actor.parameters():
            p.add_(0.05 * torch.randn_like(p))

    def error() -> float:
        with torch.no_grad():
            predicted = model.actor(torch.as_tensor(obs), deterministic=True)
        return float(((predicted - torch.as_tensor(demos.actions)) ** 2).mean())

    drifted = error()
    for _ in range(200):
        model.actor.optimizer.zero_grad()
        model.actor.optimizer.step()  # only the behaviour-cloning gradient
    assert error() < 0.5 * drifted
    env.close()


@pytest.mark.slow
def test_noisy_demonstrations_execute_noise_and_keep_the_expert_labels():
    """With noise the executed actions differ from the labels by about the noise, and the
    labels are the scripted policy's own actions in the observed states (DART)."""
    from pour_gym.agents.policies.scripted import ScriptedPourPolicy

    kwargs = {"objects": ["red_cup"]}
    sigma = (0.0, 0.0, 0.0, 0.1)
    starts = functools.partial(TrainingStarts, fill_margin=(40, 40))
    demos = collect_demonstrations("PourGym/Pour-v0", kwargs, 1, seed=5, noise=sigma,
                                   wrapper=starts, progress=False)  # fmt: skip
    assert demos.expert_actions is not None and demos.labels is demos.expert_actions
    diff = demos.actions - demos.expert_actions
    assert np.all(diff[:, :3] == 0.0)  # no noise asked on the lip
    inside = np.abs(demos.actions[:, 3]) < 1.0  # the clip at +-1 shortens the noise
    assert 0.06 < diff[inside, 3].std() < 0.14
    # Replaying the executed actions gives the same observations, and the scripted policy
    # in them gives the labels.
    env = gym.make("PourGym/Pour-v0", **kwargs)
    obs, info = env.reset(seed=5, options={"near_target": False, "fill_margin": 40})
    assert info["fill"] == info["target_amount"] + 40
    policy = ScriptedPourPolicy()
    for k in range(len(demos)):
        assert np.array_equal(obs, demos.observations[k])
        assert np.allclose(policy(obs), demos.expert_actions[k], atol=1e-6)
        obs, *_ = env.step(demos.actions[k])
    env.close()
    with pytest.raises(Exception, match="noise"):
        collect_demonstrations("PourGym/Pour-v0", kwargs, 1, seed=5, noise=-0.1)


def test_inputs_the_demonstrations_never_vary_are_hidden_from_the_network():
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from pour_gym.agents.training.warm_start import ignore_constant_inputs

    venv = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]), epsilon=0.1)
    rng = np.random.default_rng(0)
    obs = np.column_stack([rng.normal(size=200), np.full(200, 0.4), rng.normal(size=200)])
    venv.obs_rms.update(obs)
    venv.training = False
    hidden = ignore_constant_inputs(venv, obs, names=["a", "radius", "c"])
    assert hidden == ["radius"]
    raw = np.array([[1.0, 0.4, 1.0], [1.0, 0.9, 1.0]])
    seen = venv.normalize_obs(raw)
    # Another cup's radius reads as the training cup's, to a millionth of an input's scale.
    assert np.all(np.abs(seen[:, 1]) < 1e-6) and np.all(np.abs(seen[:, [0, 2]]) > 0.1)
    assert np.allclose(seen[0], seen[1], atol=1e-6)
    # SB3 un-normalises terminal observations for its replay buffer: they come back finite.
    assert np.allclose(venv.unnormalize_obs(seen), raw, atol=1e-5)
    venv.close()
