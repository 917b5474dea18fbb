"""Augmented Random Search with common episodes (agents/training/ars.py)."""

import numpy as np
import torch as th

from pour_gym.envs import POUR_V2, make

# Short episodes of a small pour: 12 steps at most.
QUICK = {"objects": "red_cup", "amount_range": (40, 80), "max_episode_steps": 12}


def _ars(venv, **kwargs):
    from pour_gym.agents.training.ars import PairedARS

    return PairedARS("LinearPolicy", venv, n_delta=2, seed=7, device="cpu",
                     policy_kwargs={"with_bias": True}, **kwargs)  # fmt: skip


def test_every_candidate_is_scored_on_the_same_episodes_as_one_env_plays_them():
    """Two candidates with the same weights score the same to the bit, whichever slot
    they take; a score is the sum of each env's first episode's rewards, as a single env
    reset from the update's seed (plus the env's index) gives them; the update's weights
    are left as they were."""
    from stable_baselines3.common.logger import configure

    from pour_gym.agents.policies.rollout import rollout
    from pour_gym.agents.training.ars import update_seed
    from pour_gym.agents.training.vector import NativeVecEnv

    venv = NativeVecEnv(POUR_V2, 2, QUICK)
    try:
        model = _ars(venv)
        model.set_logger(configure(None, []))
        _, callback = model._setup_learn(10**6)  # what learn() sets up before an update
        weights = th.linspace(-0.5, 0.5, model.n_params)
        other = -weights
        candidates = th.stack([weights, other, weights, weights])
        before = model.weights.clone()
        returns = model.evaluate_candidates(candidates, callback, None).numpy()
        assert returns[0] == returns[2] == returns[3]
        assert returns[0] != returns[1]
        assert th.equal(model.weights, before)
        # Each candidate steps both envs until the longer episode ends (12 steps at most).
        assert 0 < model.num_timesteps <= 4 * 2 * 12
        # One env at a time, from the update's seeds, acting by the same weights.
        model.policy.load_from_vector(weights)
        first = update_seed(7, 0)
        total = 0.0
        for i in range(2):
            env = make(POUR_V2, **QUICK)
            act = lambda obs: model.policy.predict(obs[None], deterministic=True)[0][0]  # noqa: E731
            total += rollout(env, act, seed=first + i).reward
            env.close()
        assert returns[0] == np.float32(total)
    finally:
        venv.close()


def test_update_seeds_follow_the_run_seed_and_stay_clear_of_evaluation_seeds():
    from pour_gym.agents.training.ars import SEED_BASE, update_seed

    seeds = [update_seed(3, k) for k in range(200)]
    assert seeds == [update_seed(3, k) for k in range(200)]
    assert len(set(seeds)) == 200 and min(seeds) >= SEED_BASE
    assert seeds != [update_seed(4, k) for k in range(200)]


def test_train_py_searches_with_ars_checkpoints_and_evaluates_its_linear_policy(tmp_path):
    """``train.py --algo ars --recipe family`` end to end at a tiny size: the run saves a
    model that loads with the weights its search stepped to (a resumed run searches on
    from them, not from zero) and acts by them, and running the command again resumes from
    the finished checkpoint and only evaluates (the same rows)."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    from pour_gym.agents.training import load_run

    out = tmp_path / "ars"
    cmd = [
        sys.executable, str(Path(__file__).resolve().parents[1] / "train.py"),
        "--env", POUR_V2, "--algo", "ars", "--recipe", "family", "--objects", "red_cup",
        "--timesteps", "100", "--n-envs", "2", "--set", "n_delta=1", "--set", "n_top=1",
        "--env-kwargs", '{"amount_range": [40, 80], "max_episode_steps": 12}',
        "--eval-objects", "red_cup", "--eval-episodes", "1", "--checkpoint-every", "48",
        "--out", str(out), "--json",
    ]  # fmt: skip
    first = subprocess.run(cmd, capture_output=True, text=True, check=True)
    doc = json.loads(first.stdout)
    assert doc["algo"] == "ars" and doc["timesteps"] == 100
    run = load_run(out / "model.zip")
    flat = th.nn.utils.parameters_to_vector(run.model.policy.parameters()).detach()
    assert th.equal(flat, run.model.weights) and flat.abs().sum() > 0
    assert run.model.num_timesteps >= 100 and list((out / "checkpoints").glob("model_*.zip"))
    again = subprocess.run(cmd, capture_output=True, text=True, check=True)
    assert json.loads(again.stdout)["rows"] == doc["rows"]
