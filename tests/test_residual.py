"""Residual learning on the scripted expert: a correction of 0 is the expert, bit for bit."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from test_agents import train_command

from pour_gym.agents.policies.residual import PHASES, ExpertResidual, ResidualConfig, ResidualPolicy
from pour_gym.agents.policies.rollout import rollout
from pour_gym.agents.policies.scripted import ScriptedPourPolicy, action_settings
from pour_gym.envs import make
from pour_gym.errors import InputError

SMALL = {"source_particles": 200, "amount_range": (40, 80)}


def _zero(obs: np.ndarray) -> np.ndarray:
    return np.zeros(4, dtype=np.float32)


def test_a_correction_of_zero_pours_as_the_expert_does():
    env = make("PourGym/Pour-v0", objects=["red_cup"], **SMALL)
    settings = action_settings("PourGym/Pour-v0")
    expert = rollout(env, ScriptedPourPolicy(**settings), seed=3, keep_infos=True)
    residual = rollout(
        env, ResidualPolicy(_zero, ResidualConfig(), settings), seed=3, keep_infos=True
    )
    env.close()
    assert expert.steps == residual.steps and expert.info["poured"] > 0
    assert [i["poured"] for i in expert.infos] == [i["poured"] for i in residual.infos]
    assert expert.reward == residual.reward


def test_the_wrapper_shows_the_expert_and_adds_the_scaled_correction():
    from gymnasium.utils.env_checker import check_env

    env = ExpertResidual(make("PourGym/Pour-v0", objects=["red_cup"], **SMALL),
                         scale=[0.05, 0.05, 0.05, 0.1])  # fmt: skip
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=1)
    inner = env.unwrapped.observation_space.shape[0]
    assert obs.shape == (inner + 4 + len(PHASES),) and env.observation_space.contains(obs)
    base, phase = obs[inner : inner + 4], obs[inner + 4 :]
    assert phase.tolist() == [1.0, 0.0, 0.0]  # the expert starts by moving the lip
    # A full correction moves each action by its scale, within the action space.
    executed = env.core.act(np.ones(4))
    assert np.allclose(
        executed, np.clip(base + np.array([0.05, 0.05, 0.05, 0.1]), -1, 1), atol=1e-6
    )
    for _ in range(60):  # the expert reaches the target and starts to tilt
        obs, *_ = env.step(np.zeros(4, dtype=np.float32))
    assert obs[inner + 4 :].tolist() != [1.0, 0.0, 0.0]
    env.close()


def test_bad_residuals_are_refused_by_name():
    with pytest.raises(InputError, match="unknown residual keys"):
        ResidualConfig.from_recipe({"scale": 0.1, "gain": 2})
    with pytest.raises(InputError, match="positive"):
        ResidualConfig.from_recipe({"scale": [0.1, -0.1, 0.1, 0.1]})
    with pytest.raises(InputError, match="unknown expert arguments"):
        ResidualConfig.from_recipe({"expert": {"tilt_control": "angle"}})
    env = make("PourGym/Pour-v0", objects=["red_cup"], obs_mode="state", **SMALL)
    with pytest.raises(InputError, match="obs_mode='features'"):
        ExpertResidual(env)
    env.close()


@pytest.mark.slow
def test_the_residual_recipe_trains_and_its_run_acts_with_the_expert(tmp_path):
    """``--recipe residual``: PPO learns a correction; the saved run evaluates as expert
    plus correction, with no wrapper around the evaluation's env."""
    from pour_gym.agents.training.runs import load_run

    out = tmp_path / "residual"
    options = (
        "--env", "PourGym/Pour-v0", "--algo", "ppo", "--recipe", "residual",
        "--objects", "red_cup", "--timesteps", "256", "--set", "n_steps=128",
        "--set", "batch_size=32", "--eval-objects", "red_cup,broad_cup", "--eval-episodes", "1",
        "--curve-every", "128", "--curve-episodes", "1",
        "--env-kwargs", json.dumps({"amount_range": [40, 80]}),
        "--set", "env_wrapper=[{pour_gym.agents.training.curriculum.TrainingStarts: "
                 "{near_target: 0.5, fill_margin: [20, 60]}}]",
    )  # fmt: skip
    done = subprocess.run(train_command(out, *options), capture_output=True, text=True,
                          check=True)  # fmt: skip
    doc = json.loads(done.stdout)
    config = json.loads((out / "config.json").read_text())
    assert config["residual"] == {"scale": [0.05, 0.05, 0.05, 0.1], "expert": {}}
    assert config["env_kwargs"]["progress_weight"] == 20.0
    # Two updates away from a correction of 0, the policy still pours as the expert does.
    assert [r["object"] for r in doc["rows"]] == ["red_cup", "broad_cup"]
    assert all(r["outcome_never_poured"] == 0 for r in doc["rows"])
    from pour_gym.agents.policies.rollout import sb3_policy

    assert isinstance(sb3_policy(load_run(out / "model.zip")), ResidualPolicy)
    missing = subprocess.run(train_command(tmp_path / "x", *options[:4], "--recipe", "nope"),
                             capture_output=True, text=True)  # fmt: skip
    assert missing.returncode == 2 and "ppo/nope" in missing.stderr


@pytest.mark.parametrize(
    ("name", "env_id"),
    [("pour-v0-red-cup-residual", "PourGym/Pour-v0"),
     ("pandapour-v0-red-cup-residual", "PourGym/PandaPour-v0")],
)  # fmt: skip
def test_the_shipped_residuals_act_with_their_expert_and_pour(name, env_id):
    """A shipped model loads as expert plus correction and pours a small episode (through
    the arm, for PandaPour-v0's)."""
    from pour_gym.agents.evaluation.evaluate import load_policy

    loaded = load_policy(name)
    assert isinstance(loaded.policy, ResidualPolicy) and loaded.env_id == env_id
    env = make(env_id, objects=["red_cup"], **SMALL)
    episode = rollout(env, loaded.policy, seed=5)
    env.close()
    assert episode.info["poured"] > 0 and episode.info["spilled"] == 0
