"""The shipped reward-only PPO model on the red cup, by its mean action and by its samples.

Run from the repository's root: ``python docs/learning-from-reward/mean-and-sampled/run.py``
(about a minute); it prints one line per episode: the outcome, the steps, what was poured
against the target and its tolerance, the tilt at the end and at most (deg); then, for each
way of acting, the mean of poured / target.
"""

import numpy as np

import pour_gym  # noqa: F401  (registers the ids)
from pour_gym.agents.evaluation.evaluate import load_policy
from pour_gym.envs import make, task_of

for actions in ("mean", "sampled"):
    loaded = load_policy("pour-v1-red-cup-features", actions=actions)
    env = make(loaded.env_id, objects="red_cup", **loaded.env_kwargs)
    task = task_of(loaded.env_id)
    shares = []
    for seed in range(10_000, 10_010):
        obs, info = env.reset(seed=seed)
        if hasattr(loaded.policy, "reset"):
            loaded.policy.reset(seed=seed)
        tilts, done, steps = [], False, 0
        while not done:
            obs, _, terminated, truncated, info = env.step(loaded.policy(obs))
            tilts.append(env.unwrapped.tilt)
            steps += 1
            done = terminated or truncated
        print(
            f"{actions:8s} seed {seed} {task.outcome(info):13s} steps {steps:3d} "
            f"poured {info['poured']:3d} of {info['target_amount']:3d} "
            f"(tolerance {info['tolerance']:4.1f}) tilt at the end {tilts[-1]:4.1f}, "
            f"at most {max(tilts):4.1f}"
        )
        shares.append(info["poured"] / info["target_amount"])
    print(f"{actions}: poured / target {np.mean(shares):.3f} on average")
    env.close()
