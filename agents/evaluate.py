"""Evaluating a policy on every container: success rate, amount error and spill per object.

A policy is anything that maps an observation to an action (see
:mod:`pour_gym.agents.rollout`): an SB3 model, the scripted policy, or a parameterised
policy from policy search. Objects the policy never trained on are marked, which is the
generalisation the thesis argues for. For Pour-v0 the rows are (source, target) pairs:
each object as both (the default), or every source with every target (a matrix).
"""

from __future__ import annotations

import itertools
import sys
from collections.abc import Callable, Iterable

import numpy as np
from tqdm import tqdm

from pour_gym.agents.rollout import rollout
from pour_gym.envs import POUR_ENV_IDS


def evaluate_policy(
    policy: Callable[[np.ndarray], np.ndarray],
    env_id: str,
    objects: Iterable[str] = (),
    episodes: int = 5,
    seed: int = 10_000,
    env_kwargs: dict | None = None,
    trained_on: Iterable[str] = (),
    source_objects: Iterable[str] | None = None,
    target_objects: Iterable[str] | None = None,
) -> dict:
    """Run ``episodes`` episodes per object (or per source-target pair) and summarise them.

    Args:
        policy: observation -> action (``reset()`` called at every episode if it has one).
        env_id: a registered ``PourGym/`` id.
        objects: containers (names or mesh paths); for Pour-v0 each is the source and the
            target of its row.
        episodes: episodes per row.
        seed: seed of the first episode (row k, episode e uses ``seed + k * episodes + e``).
        env_kwargs: more keyword arguments for ``gymnasium.make``.
        trained_on: objects the policy was trained on (marked in the rows).
        source_objects: Pour-v0: sources of a matrix of rows (with ``target_objects``).
        target_objects: Pour-v0: targets of a matrix of rows (default: ``objects``).

    Returns:
        ``{"env", "episodes", "rows": [{"object", "source", "target", "trained_on",
        "success", "reward", "amount_error", "spilled", "corrections"}...], "mean": {...}}``;
        the Pour-v0 columns are None for the one-step environments.
    """
    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments

    objects = list(objects)
    if source_objects is not None or target_objects is not None:
        if env_id not in POUR_ENV_IDS:
            raise ValueError(f"sources and targets are for {POUR_ENV_IDS}, not {env_id}")
        sources = list(source_objects if source_objects is not None else objects)
        targets = list(target_objects if target_objects is not None else objects)
        pairs = list(itertools.product(sources, targets))
    else:
        pairs = [(name, name) for name in objects]
    if not pairs:
        raise ValueError("no containers to evaluate on")
    trained = set(trained_on)
    rows = []
    bar = tqdm(total=len(pairs) * episodes, desc=f"evaluate {env_id}", file=sys.stderr)
    pour = env_id in POUR_ENV_IDS
    for k, (source, target) in enumerate(pairs):
        if pour:
            env = gym.make(
                env_id, source_objects=[source], target_objects=[target], **(env_kwargs or {})
            )
        else:
            env = gym.make(env_id, objects=[source], **(env_kwargs or {}))
        results = []
        for ep in range(episodes):  # the bar counts episodes, as its total does
            results.append(rollout(env, policy, seed=seed + k * episodes + ep))
            bar.update()
        env.close()
        infos = [r.info for r in results]
        rows.append(
            {
                "object": source if source == target else f"{source} -> {target}",
                "source": source,
                "target": target if pour else None,
                "trained_on": source in trained and (target in trained or not pour),
                "success": float(np.mean([i["is_success"] for i in infos])),
                "reward": float(np.mean([r.reward for r in results])),
                "amount_error": float(
                    np.mean([abs(i["poured"] - i["target_amount"]) for i in infos])
                )
                if pour
                else None,
                "spilled": float(np.mean([i["spilled"] for i in infos])) if pour else None,
                "corrections": float(np.mean([i["fluid_corrections"] for i in infos]))
                if pour
                else None,
            }
        )
    bar.close()
    mean = {
        key: float(np.mean([r[key] for r in rows]))
        for key in ("success", "reward", "amount_error", "spilled")
        if rows[0][key] is not None
    }
    unseen = [r for r in rows if not r["trained_on"]]
    if unseen and len(unseen) < len(rows):
        mean["success_unseen"] = float(np.mean([r["success"] for r in unseen]))
    return {"env": env_id, "episodes": episodes, "rows": rows, "mean": mean}


def evaluation_table(result: dict) -> str:
    """Markdown table of :func:`evaluate_policy` (objects trained on marked with *)."""
    lines = [
        "| object | success | mean reward | mean amount error (particles) | mean spilled |",
        "|---|---:|---:|---:|---:|",
    ]
    for r in result["rows"]:
        name = r["object"] + (" *" if r["trained_on"] else "")
        err = "" if r["amount_error"] is None else f"{r['amount_error']:.1f}"
        spill = "" if r["spilled"] is None else f"{r['spilled']:.1f}"
        lines.append(f"| {name} | {r['success']:.2f} | {r['reward']:.2f} | {err} | {spill} |")
    m = result["mean"]
    err = f"{m['amount_error']:.1f}" if "amount_error" in m else ""
    spill = f"{m['spilled']:.2f}" if "spilled" in m else ""
    lines.append(f"| **mean** | **{m['success']:.2f}** | {m['reward']:.2f} | {err} | {spill} |")
    if "success_unseen" in m:
        lines.append(f"\nsuccess on containers never trained on: {m['success_unseen']:.2f}")
    lines.append("\n\\* trained on this object")
    return "\n".join(lines)
