"""Which pour the reward prefers: discounted returns of a policy and of the scripted expert.

PPO maximises the return discounted by its gamma, not the success rate. This scores
policies by both on the same episodes: ``procedural:test`` members 0..N-1, each as source
and target, seed 60000 + 2k (the first of each member's two evaluation episodes), on
PourGym/Pour-v1 (docs/learning-from-reward.md, "Over the family: PPO pours in a flick").

    python docs/learning-from-reward/discounted_returns.py [MODEL ...] [--members 50]

Each MODEL is a run folder or a shipped model's name (default: pour-v1-family-sde), acting
by its mean action; the scripted expert is always scored. Prints one row per policy: the
success rate, the mean episode length (steps) and the mean return discounted by each gamma
(1 = undiscounted).
"""

import argparse

import gymnasium as gym
import numpy as np

import pour_gym  # noqa: F401 (registers the envs)
from pour_gym.agents.evaluation.evaluate import load_policy
from pour_gym.agents.policies.rollout import rollout
from pour_gym.report.tables import markdown_table

ENV = "PourGym/Pour-v1"
GAMMAS = (1.0, 0.999, 0.998, 0.995, 0.99)
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("models", nargs="*", default=["pour-v1-family-sde"])
parser.add_argument("--members", type=int, default=50)
args = parser.parse_args()

policies = {"scripted expert": load_policy("scripted", ENV)}
for name in args.models:
    policies[f"{name} (mean action)"] = load_policy(name, ENV, actions="mean")

rows = []
for label, loaded in policies.items():
    success, steps, returns = [], [], []
    for k in range(args.members):
        env = gym.make(ENV, objects=[f"procedural:test#{k}"], num_threads=1, **loaded.env_kwargs)
        rewards: list[float] = []
        episode = rollout(env, loaded.policy, seed=60000 + 2 * k,
                          on_step=lambda step, into=rewards: into.append(step.reward))  # fmt: skip
        env.close()
        r = np.array(rewards)
        success.append(episode.info["is_success"])
        steps.append(len(r))
        returns.append([float((g ** np.arange(len(r)) * r).sum()) for g in GAMMAS])
    mean = np.mean(returns, axis=0)
    rows.append([label, f"{np.mean(success):.2f}", f"{np.mean(steps):.0f}",
                 *(f"{x:.2f}" for x in mean)])  # fmt: skip
head = ["policy", "success", "steps", *(f"return, gamma {g:g}" for g in GAMMAS)]
print(markdown_table(head, rows, align="lrr" + "r" * len(GAMMAS)))
