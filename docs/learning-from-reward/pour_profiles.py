"""How a policy pours over time, beside the scripted expert on the same episode.

Plots the source's tilt and what has left it (over the target amount T) against time,
one episode per policy with the same seed and containers: PPO's shipped family policy by
its mean action pours its amount in a flick, the expert in a regulated stream
(docs/learning-from-reward.md, "Over the family: PPO pours in a flick").

    python docs/learning-from-reward/pour_profiles.py [MODEL ...] [--object NAME] [--seed N]

Each MODEL is a run folder or a shipped model's name (default: pour-v1-family-sde); the
episode is NAME as source and target (default procedural:test#53) at seed N (60106).
Writes docs/learning-from-reward/pour_profiles.png.
"""

import argparse
from pathlib import Path

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import pour_gym  # noqa: F401 (registers the envs)
from pour_gym.agents.evaluation.evaluate import load_policy
from pour_gym.agents.policies.rollout import rollout
from pour_gym.envs.rules import out_of_source
from pour_gym.envs.task import pour_profile

ENV = "PourGym/Pour-v1"
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("models", nargs="*", default=["pour-v1-family-sde"])
parser.add_argument("--object", default="procedural:test#53")
parser.add_argument("--seed", type=int, default=60106)
args = parser.parse_args()

policies = {"scripted expert": load_policy("scripted", ENV)}
for name in args.models:
    policies[f"{Path(name).name} (mean action)"] = load_policy(name, ENV, actions="mean")

fig, (ax_tilt, ax_out) = plt.subplots(2, 1, figsize=(7, 6.2), sharex=True)
for label, loaded in policies.items():
    env = gym.make(ENV, objects=[args.object], num_threads=1, **loaded.env_kwargs)
    episode = rollout(env, loaded.policy, seed=args.seed, keep_infos=True)
    env.close()
    infos = episode.infos
    t = env.unwrapped.dt * np.arange(1, len(infos) + 1)
    amount = infos[-1]["target_amount"]
    out = np.maximum.accumulate([out_of_source(i) for i in infos]) / amount
    profile = pour_profile(infos, env.unwrapped.dt)
    outcome = "success" if infos[-1]["is_success"] else "failed"
    text = (f"{label}: poured {infos[-1]['poured']} of {amount}, {outcome}; stream "
            f"{profile['pour_seconds']:.1f} s, peak {profile['peak_flow']:.2f} T/s")  # fmt: skip
    print(text)
    (line,) = ax_tilt.plot(t, [i["tilt_deg"] for i in infos], label=text)
    ax_out.plot(t, out, color=line.get_color())
tol = infos[-1]["tolerance"] / amount
ax_out.axhspan(1 - tol, 1 + tol, color="0.85", label="target amount, within tolerance")
ax_tilt.set_ylabel("tilt, deg")
ax_out.set_ylabel("out of the source / T")
ax_out.set_xlabel("time, s")
ax_tilt.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.02), frameon=False)
ax_out.legend(fontsize=7, loc="center right")
fig.suptitle(f"{ENV}, {args.object}, seed {args.seed}", fontsize=9)
fig.tight_layout()
path = Path(__file__).with_name("pour_profiles.png")
fig.savefig(path, dpi=110)
print(f"wrote {path}")
