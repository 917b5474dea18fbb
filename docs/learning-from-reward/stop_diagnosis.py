"""Where a Pour-v5 policy stops, episode by episode: the signed amount error and its cause.

Run from the repository's root: ``python docs/learning-from-reward/stop_diagnosis.py
POLICY MEMBERS`` with POLICY a model (``pour-v5-family``, a ``model.zip``) or ``scripted``,
scored by its mean action on the first episode of each of the first MEMBERS members of
``procedural:test`` as source and target (the evaluation's seed: 60000 + 2 k for member
k). Per episode: the target amount T and the tolerance, the signed error (poured - T),
what was out of the source (poured, in flight, spilled) when the policy first named a
stop (an action at or below ``FLOW_STOP``) after the pour began, what left after it, and
the stream measured over the second before it (target amounts a second). Then the
summary over the episodes that succeeded and over all: the mean and spread of the signed
error, the mean absolute error, and the mean that left after the stop.
"""

import sys
import warnings

import numpy as np

import pour_gym  # noqa: F401  (registers the envs)
from pour_gym.agents.evaluation.evaluate import load_policy
from pour_gym.agents.policies.rollout import rollout
from pour_gym.envs.actions import FLOW_STOP
from pour_gym.envs.registry import make

warnings.filterwarnings("ignore")
ENV = "PourGym/Pour-v5"


def episode_stop(policy, member: int, env_kwargs: dict) -> dict:
    """One episode of ``policy`` on member ``member`` as source and target, and its stop."""
    name = f"procedural:test#{member}"
    env = make(ENV, source_objects=[name], target_objects=[name], num_threads=1, **env_kwargs)
    record = []

    def on_step(step) -> None:
        i = step.info
        record.append((float(step.action[3]), i["poured"] + i["in_flight"] + i["spilled"]))

    episode = rollout(env, policy, seed=60000 + 2 * member, on_step=on_step)
    env.close()
    info = episode.info
    target = info["target_amount"]
    out = [0.0] + [r[1] for r in record]  # out[j]: out of the source before step j
    began = next((j for j in range(len(record)) if out[j + 1] > 0), None)
    named = [] if began is None else range(began, len(record))
    stop = next((j for j in named if record[j][0] <= FLOW_STOP), None)
    at_stop, before = float("nan"), float("nan")
    if stop:
        at_stop = out[stop]
        # The stream over the second before the stop (10 steps), target amounts a second.
        back = min(stop, 10)
        before = (out[stop] - out[stop - back]) / target / (back * 0.1)
    return {
        "T": target,
        "tolerance": info["tolerance"],
        "error": info["poured"] - target,
        "spilled": info["spilled"],
        "success": bool(info["is_success"]),
        "at_stop": at_stop,
        "after_stop": out[-1] - at_stop,
        "stream_before": before,
        "steps": episode.steps,
    }


def main(name: str, members: int) -> None:
    """Print one line per episode of ``name``, then the summary."""
    loaded = load_policy(name, ENV, actions=None if name == "scripted" else "mean")
    kwargs = dict(getattr(loaded, "env_kwargs", None) or {})
    rows = []
    for k in range(members):
        r = episode_stop(loaded.policy, k, kwargs)
        rows.append(r)
        print(
            f"{k:3d} T {r['T']:4d} tol {r['tolerance']:4.1f} error {r['error']:+4d} "
            f"spilled {r['spilled']:3d} out at stop {r['at_stop']:5.0f} "
            f"after {r['after_stop']:4.0f} "
            f"stream before {r['stream_before']:.2f} T/s steps {r['steps']:3d} "
            f"{'success' if r['success'] else 'failed'}",
            flush=True,
        )
    for label, chosen in (("succeeded", [r for r in rows if r["success"]]), ("all", rows)):
        e = np.array([r["error"] for r in chosen], float)
        after = np.array([r["after_stop"] for r in chosen], float)
        print(
            f"{label}: {len(chosen)} episodes, signed error mean {e.mean():+.2f} "
            f"sd {e.std(ddof=1):.2f}, |error| {np.abs(e).mean():.2f}, "
            f"left after the stop {np.nanmean(after):.2f}"
        )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
