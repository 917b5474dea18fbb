"""Every registered environment: API checks, determinism, pickling, bad actions, user meshes.

And the scripted features policy on Pour-v0: at least 80 % success on the train split
(red cup into red cup) and on the test split (the other thesis objects).
"""

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import pour_gym  # noqa: F401 - registers the environments
from pour_gym.agents.scripted import ScriptedPourPolicy
from pour_gym.envs import ENV_IDS
from pour_gym.objects import cylinder_cup

# Small fluids keep the checks quick; the defaults are exercised by the policy test.
FAST = {
    "PourGym/Pour-v0": {"source_particles": 300, "amount_range": (40, 80)},
    "PourGym/ParticleDrop-v0": {},
    "PourGym/TiltPour-v0": {},
}


def make(env_id, **kwargs):
    return gym.make(env_id, **{**FAST[env_id], **kwargs})


def test_ids_are_registered():
    assert set(ENV_IDS) == {"PourGym/Pour-v0", "PourGym/ParticleDrop-v0", "PourGym/TiltPour-v0"}
    for env_id in ENV_IDS:
        assert env_id in gym.registry


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_and_sb3_checks(env_id):
    env = make(env_id)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("obs_mode", ["features", "state"])
def test_same_seed_same_rollout(env_id, obs_mode):
    def rollout():
        env = make(env_id, obs_mode=obs_mode)
        obs, _ = env.reset(seed=7)
        env.action_space.seed(3)
        out = [obs]
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            out += [obs, np.array([reward])]
            assert env.observation_space.contains(obs)
            terms = sum(v for k, v in info.items() if k.startswith("reward_"))
            assert terms == pytest.approx(reward)
            if terminated or truncated:
                obs, _ = env.reset()
                out.append(obs)
        env.close()
        return np.concatenate([np.ravel(x) for x in out])

    assert np.array_equal(rollout(), rollout())


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_pickle_bad_actions_and_close_twice(env_id):
    env = make(env_id)
    env.reset(seed=0)
    copy = pickle.loads(pickle.dumps(env))
    obs_a, _ = env.reset(seed=1)
    obs_b, _ = copy.reset(seed=1)
    assert np.array_equal(obs_a, obs_b)
    shape = env.action_space.shape
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.full(shape, np.nan))
    with pytest.raises(ValueError, match=r"\[-1, 1\]"):
        env.step(np.full(shape, 3.0))
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"colour": "red"})
    frame = make(env_id, render_mode="rgb_array")
    frame.reset(seed=0)
    image = frame.render()
    assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8
    frame.close()
    env.close()
    env.close()
    copy.close()


def test_unknown_containers_and_arguments_are_refused():
    with pytest.raises(ValueError, match="not a container"):
        gym.make("PourGym/Pour-v0", objects="teapot")
    with pytest.raises(ValueError, match="obs_mode"):
        gym.make("PourGym/TiltPour-v0", obs_mode="pixels")
    with pytest.raises(ValueError, match="fluid"):
        gym.make("PourGym/ParticleDrop-v0", fluid="sph")


def test_a_user_mesh_works_as_a_container(tmp_path):
    # A plain cylinder cup as the user's own mesh file, labelled on the fly.
    path = tmp_path / "my_cup.stl"
    cylinder_cup(0.035, 0.09).export(path)
    env = gym.make("PourGym/TiltPour-v0", objects=[str(path)])
    env.reset(seed=0, options={"fill": 0.7, "tilt_deg": 60.0})
    _, _, _, _, info = env.step(np.array([1.0]))
    assert info["container"] == str(path)
    assert info["label"] is True  # 70 % full at 60 degrees: tan 60 > (H - h) / R
    drop = gym.make("PourGym/ParticleDrop-v0", objects=str(path))
    drop.reset(seed=0, options={"spawn": [0.0, 0.0, 0.15], "fill": 0.0})
    _, reward, _, _, info = drop.step(np.array([1.0]))
    assert info["label"] is True and reward == 1.0
    env.close()
    drop.close()


def test_tilt_labels_follow_the_onset_angle():
    """The hydrostatic label flips at tan(theta) = (H - h) / R for the cylinder of the test."""
    env = gym.make("PourGym/TiltPour-v0", objects="standard_cup")
    labels = []
    for tilt in (5.0, 30.0, 60.0, 85.0):
        env.reset(seed=0, options={"fill": 0.5, "tilt_deg": tilt})
        _, _, _, _, info = env.step(np.array([0.0]))
        labels.append(info["label"])
    assert labels == sorted(labels) and labels[0] is False and labels[-1] is True
    env.close()


def run_scripted(objects, episodes, seed=0):
    env = gym.make("PourGym/Pour-v0", objects=objects)
    policy = ScriptedPourPolicy()
    results = []
    for ep in range(episodes):
        obs, info = env.reset(seed=seed + ep)
        policy.reset()
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            done = terminated or truncated
        results.append(info)
    env.close()
    return results


@pytest.mark.parametrize("split", ["train", "test"])
def test_scripted_policy_pours_the_amount(split):
    results = run_scripted(split, 10)
    success = np.mean([r["is_success"] for r in results])
    detail = [(r["source"], r["target"], r["poured"], r["target_amount"]) for r in results]
    assert success >= 0.8, detail
    for r in results:  # every particle accounted for
        assert r["in_source"] + r["poured"] + r["in_flight"] + r["spilled"] == r["fill"]


def test_experiments_at_tiny_size(tmp_path):
    """Both thesis experiments run end to end and their numbers are sane."""
    from pour_gym.agents.experiments import roc_curve, run_experiment

    fpr, tpr = roc_curve(np.array([0.9, 0.8, 0.3, 0.1]), np.array([1, 1, 0, 0], bool))
    assert fpr[0] == tpr[0] == 0.0 and fpr[-1] == tpr[-1] == 1.0
    for which in ("tilt", "drop"):
        doc = run_experiment(which, episodes=12, out=tmp_path, objects=("red_cup", "standard_cup"))
        assert set(doc["auc"]) == {"red_cup", "standard_cup", "all"}
        assert all(0.5 <= v <= 1.0 for v in doc["auc"].values())
        assert (tmp_path / f"roc_{which}.png").stat().st_size > 10_000
        assert (tmp_path / f"dataset_{which}.npz").is_file()
