"""Policy search (the thesis's future work, chapter 8): CMA-ES over a policy's parameters.

The searched policy is the scripted features policy of Pour-v0
(:class:`pour_gym.agents.scripted.ScriptedPourPolicy`); its four parameters (where the lip
goes, how fast it tilts, how much flow it holds, how early it tilts back) are searched
with CMA-ES (the ``cma`` package) to maximise the mean episode return on the training
containers. Every candidate is scored on the same seeds (common random numbers), so that
candidates differ by their parameters, not by their luck.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pour_gym.agents.scripted import ScriptedPourPolicy
from pour_gym.assets import expand_containers

# Searched parameters: name, lower bound, upper bound (CMA-ES works in [0, 1] per axis).
PARAMETERS = (
    ("lip_offset", 0.2, 0.9),
    ("slow_rate", 0.03, 0.4),
    ("lead", 0.5, 3.0),
    ("flow", 0.01, 0.15),
)


def to_policy(u: np.ndarray) -> ScriptedPourPolicy:
    """The policy of a point of the unit cube."""
    u = np.clip(np.asarray(u, float), 0.0, 1.0)
    kwargs = {name: lo + x * (hi - lo) for (name, lo, hi), x in zip(PARAMETERS, u, strict=True)}
    return ScriptedPourPolicy(**kwargs)


def episode_returns(policy: ScriptedPourPolicy, env, seeds: list[int]) -> list[dict]:
    """Run one episode per seed; the last infos with the returns."""
    out = []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        policy.reset()
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            total += float(reward)
            done = terminated or truncated
        out.append({**info, "return": total})
    return out


def search(
    objects="train",
    generations: int = 6,
    population: int = 6,
    episodes: int = 3,
    seed: int = 0,
    out: str | Path | None = None,
    env_kwargs: dict | None = None,
) -> dict:
    """CMA-ES over the scripted policy's parameters on Pour-v0.

    Args:
        objects: containers to search on.
        generations: CMA-ES iterations.
        population: candidates per generation.
        episodes: episodes per candidate (the same seeds for all).
        seed: seed of CMA-ES and of the episodes.
        out: folder for ``search.json`` (optional).
        env_kwargs: more Pour-v0 arguments (e.g. a smaller ``source_particles``).

    Returns:
        ``{"best": {param: value}, "best_return": x, "start_return": x, "history": [...]}``.
    """
    import cma
    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments

    env = gym.make(
        "PourGym/Pour-v0", objects=list(expand_containers(objects)), **(env_kwargs or {})
    )
    seeds = [seed * 1000 + k for k in range(episodes)]
    # Start at the hand-set parameters.
    default = ScriptedPourPolicy()
    x0 = [(getattr(default, n) - lo) / (hi - lo) for n, lo, hi in PARAMETERS]
    start = float(np.mean([r["return"] for r in episode_returns(default, env, seeds)]))
    es = cma.CMAEvolutionStrategy(
        x0, 0.2, {"bounds": [0.0, 1.0], "popsize": population, "seed": seed + 1, "verbose": -9}
    )
    history = []
    bar = tqdm(total=generations * population, desc="policy search", file=sys.stderr)
    for g in range(generations):
        candidates = es.ask()
        scores = []
        for u in candidates:
            results = episode_returns(to_policy(u), env, seeds)
            scores.append(float(np.mean([r["return"] for r in results])))
            bar.update()
        es.tell(candidates, [-s for s in scores])  # CMA-ES minimises
        history.append({"generation": g, "best": max(scores), "mean": float(np.mean(scores))})
    bar.close()
    env.close()
    best_u = es.result.xbest
    best = {n: lo + x * (hi - lo) for (n, lo, hi), x in zip(PARAMETERS, best_u, strict=True)}
    doc = {
        "objects": list(expand_containers(objects)),
        "episodes_per_candidate": episodes,
        "start": {n: getattr(default, n) for n, _, _ in PARAMETERS},
        "start_return": start,
        "best": best,
        "best_return": float(-es.result.fbest),
        "history": history,
    }
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "search.json").write_text(json.dumps(doc, indent=2) + "\n")
    return doc
