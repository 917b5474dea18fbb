"""Pour-v0 in several processes, as RL libraries run it: SB3's SubprocVecEnv (spawn and
forkserver workers) and Gymnasium's async vector env with its default start method, after
the parent process has stepped an environment of its own."""

import functools
import subprocess
import sys

import numpy as np
import pytest
from stable_baselines3.common.vec_env import SubprocVecEnv

import pour_gym  # noqa: F401 - registers the environments

SMALL = {"source_particles": 150, "amount_range": (20, 40), "objects": "red_cup"}


def _make():
    import gymnasium as gym

    return gym.make("PourGym/Pour-v0", **SMALL)


@pytest.mark.slow
@pytest.mark.parametrize("start_method", ["spawn", "forkserver"])
def test_subprocess_workers_step_pour(start_method):
    venv = SubprocVecEnv([_make, _make], start_method=start_method)
    venv.seed(0)
    obs = venv.reset()
    assert obs.shape == (2, 16)
    for _ in range(5):
        obs, _rewards, _dones, infos = venv.step(np.zeros((2, 4), dtype=np.float32))
    assert np.isfinite(obs).all() and len(infos) == 2
    # A worker process runs its fluid on one thread.
    assert venv.get_attr("num_threads") == [None, None]
    threads = venv.env_method("get_wrapper_attr", "world")
    assert [w.fluid.num_threads for w in threads] == [1, 1]
    venv.close()


@pytest.mark.slow
def test_async_make_vec_after_the_parent_stepped(tmp_path):
    # In a fresh interpreter: the parent steps an env on its default threads, then
    # Gymnasium forks (its default start method on Linux) two workers.
    script = tmp_path / "run.py"
    script.write_text(
        "import gymnasium as gym, numpy as np, pour_gym\n"
        f"kw = {SMALL!r}\n"
        "env = gym.make('PourGym/Pour-v0', **kw)\n"
        "env.reset(seed=0)\n"
        "for _ in range(3): env.step(env.action_space.sample())\n"
        "venv = gym.make_vec('PourGym/Pour-v0', num_envs=2, vectorization_mode='async', **kw)\n"
        "venv.reset(seed=0)\n"
        "for _ in range(5): venv.step(venv.action_space.sample())\n"
        "venv.close(); print('ok')\n"
    )
    proc = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stderr[-2000:]
    assert "abort" not in proc.stderr.lower()


def test_fluid_threads_default_to_one_in_a_worker():
    from multiprocessing import get_context

    from pour_gym.fluid.pbf import default_threads

    with get_context("spawn").Pool(1) as pool:
        assert pool.apply(functools.partial(default_threads)) == 1


@pytest.mark.slow
def test_workers_compute_what_one_env_computes_bit_for_bit():
    """The same seeds and actions give the same observations and rewards in SB3's worker
    processes as in one env of this process (what ``pour-gym bench envs`` relies on to
    compare one env with two workers on equal work)."""
    import gymnasium as gym

    steps = 30
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.0, 1.0, size=(steps, 2, 4)).astype(np.float32)
    venv = SubprocVecEnv([_make, _make], start_method="forkserver")
    venv.seed(7)
    vec_obs = [venv.reset()]
    vec_rewards = []
    for k in range(steps):
        obs, rewards, _dones, _infos = venv.step(actions[k])
        vec_obs.append(obs)
        vec_rewards.append(rewards)
    venv.close()
    env = gym.make("PourGym/Pour-v0", num_threads=1, **SMALL)
    for i in range(2):
        obs, _ = env.reset(seed=7 + i)
        assert np.array_equal(obs, vec_obs[0][i])
        for k in range(steps):
            obs, reward, terminated, truncated, _ = env.step(actions[k, i])
            assert not (terminated or truncated)  # 30 steps end no episode here
            assert np.array_equal(obs, vec_obs[k + 1][i]), f"worker {i}, step {k}"
            assert reward == vec_rewards[k][i]
    env.close()
