"""A Pour-v1 step's cost by particle spacing: the scripted expert on the red cup, one thread.

Each spacing's env is made and warmed up first; then three episodes of each, the spacings
taken in turn (so that a machine's drift falls on all of them alike). Prints the median
seconds per step and its ratio to 5 mm's (docs/liquids.md, "The particle spacing").

    python docs/liquids/spacing_speed.py [7,5,3.5,2.5]
"""

import sys
import time

import gymnasium as gym
import numpy as np

import pour_gym  # noqa: F401 (registers the envs)
from pour_gym.agents.policies.rollout import rollout
from pour_gym.agents.policies.scripted import ScriptedPourPolicy, action_settings

ENV = "PourGym/Pour-v1"
mm = [float(x) for x in (sys.argv[1] if len(sys.argv) > 1 else "7,5,3.5,2.5").split(",")]
envs = {s: gym.make(ENV, objects="red_cup", spacing=s / 1000, num_threads=1) for s in mm}
policy = ScriptedPourPolicy(**action_settings(ENV))
for env in envs.values():
    rollout(env, policy, seed=0)  # compile and warm up
per_step = {s: [] for s in mm}
for rep in range(3):
    for s, env in envs.items():
        start = time.perf_counter()
        episode = rollout(env, policy, seed=1000 + rep)
        per_step[s].append((time.perf_counter() - start) / episode.steps)
base = np.median(per_step[5.0]) if 5.0 in per_step else None
for s in mm:
    t = np.median(per_step[s])
    ratio = f" ({t / base:.2f} of 5 mm)" if base else ""
    print(f"{s:g} mm: {1000 * t:.1f} ms a step{ratio}")
