"""Evaluating a policy on every container: success rate, amount error and spill per object.

A policy is anything that maps an observation to an action: an SB3 model (its
``predict``), the scripted policy, or a parameterised policy from policy search. Objects the
policy never trained on are marked, which is the generalisation the thesis argues for.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable

import numpy as np
from tqdm import tqdm

Policy = Callable[[np.ndarray], np.ndarray]


def evaluate_policy(
    policy: Policy,
    env_id: str,
    objects: Iterable[str],
    episodes: int,
    seed: int = 10_000,
    env_kwargs: dict | None = None,
    reset: Callable[[], None] | None = None,
    trained_on: Iterable[str] = (),
) -> dict:
    """Run ``episodes`` episodes per object and summarise them.

    For Pour-v0 each object is the source and the target (the same container on both
    sides keeps one number per object); the one-step environments use it as their
    container.

    Args:
        policy: observation -> action.
        env_id: a registered ``PourGym/`` id.
        objects: containers (names or mesh paths).
        episodes: episodes per object.
        seed: seed of the first episode.
        env_kwargs: more keyword arguments for ``gymnasium.make``.
        reset: called at the start of every episode (for stateful policies).
        trained_on: objects the policy was trained on (marked in the rows).

    Returns:
        ``{"env", "episodes", "rows": [{"object", "trained_on", "success", "reward",
        "amount_error", "spilled"}...], "mean": {...}}``; the Pour-v0 columns are None for
        the one-step environments.
    """
    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments

    objects = list(objects)
    trained = set(trained_on)
    rows = []
    bar = tqdm(total=len(objects) * episodes, desc=f"evaluate {env_id}", file=sys.stderr)
    for k, name in enumerate(objects):
        env = gym.make(env_id, objects=[name], **(env_kwargs or {}))
        results = []
        for ep in range(episodes):
            obs, info = env.reset(seed=seed + k * episodes + ep)
            if reset is not None:
                reset()
            total, done = 0.0, False
            while not done:
                obs, reward, terminated, truncated, info = env.step(policy(obs))
                total += float(reward)
                done = terminated or truncated
            results.append((info, total))
            bar.update()
        env.close()
        pour = "target_amount" in results[0][0]
        rows.append(
            {
                "object": name,
                "trained_on": name in trained,
                "success": float(np.mean([i["is_success"] for i, _ in results])),
                "reward": float(np.mean([r for _, r in results])),
                "amount_error": float(
                    np.mean([abs(i["poured"] - i["target_amount"]) for i, _ in results])
                )
                if pour
                else None,
                "spilled": float(np.mean([i["spilled"] for i, _ in results])) if pour else None,
            }
        )
    bar.close()
    mean = {
        key: float(np.mean([r[key] for r in rows]))
        for key in ("success", "reward", "amount_error", "spilled")
        if rows and rows[0][key] is not None
    }
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
    lines.append("\n\\* trained on this object")
    return "\n".join(lines)


def sb3_policy(model) -> Policy:
    """An SB3 model as a deterministic policy."""

    def act(obs: np.ndarray) -> np.ndarray:
        action, _ = model.predict(obs, deterministic=True)
        return action

    return act
