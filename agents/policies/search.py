"""Policy search (the thesis's future work, chapter 8): CMA-ES over a policy's parameters.

The searched policy is the scripted features policy of Pour-v0
(:class:`pour_gym.agents.policies.scripted.ScriptedPourPolicy`); its parameters (where the lip goes,
how fast it tilts, how it regulates the flow, how early it tilts back) are searched with
CMA-ES (the ``cma`` package) in the unit cube of their ranges. The objective is the mean
episode return, or, for a fixed target amount, the mean absolute amount error in
particles (spilled particles count twice), which is what the proof of concept measures.
Every candidate is scored on the same seeds (common random numbers), so that candidates
differ by their parameters, not by their luck.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pour_gym.agents.cluster import map_tasks, ray_session
from pour_gym.agents.policies.rollout import rollout
from pour_gym.agents.policies.scripted import ScriptedPourPolicy
from pour_gym.assets import expand_containers
from pour_gym.envs import POUR_V0
from pour_gym.errors import InputError

# Searched parameters: name, lower bound, upper bound (CMA-ES works in [0, 1] per axis).
PARAMETERS = (
    ("lip_offset", 0.2, 0.9),
    ("slow_rate", 0.03, 0.4),
    ("lead", 0.0, 2.0),
    ("share", 0.05, 0.5),
    ("min_flow", 0.01, 0.15),
    ("min_particles", 0.5, 4.0),
    ("gain", 0.5, 6.0),
    ("back_rate", 0.05, 1.0),
)
OBJECTIVES = ("return", "error")
STARTS = ("search", "expert")
# Where the search starts: fixed here, not read from the policy's defaults (which are tuned
# for Pour-v0's usual 100-300 particles and may change), so a committed search repeats.
START = {
    "lip_offset": 0.6,
    "slow_rate": 0.12,
    "lead": 0.5,
    "share": 0.15,
    "min_flow": 0.05,
    "min_particles": 1.5,
    "gain": 2.0,
    "back_rate": 1.0,
}


def start_parameters(start: str) -> dict[str, float]:
    """Where a search starts.

    ``"search"``: :data:`START`; ``"expert"``: the scripted expert's own defaults (a search
    that improves on the expert it starts from).
    """
    if start not in STARTS:
        raise InputError(f"start must be one of {STARTS}, not {start!r}")
    if start == "search":
        return dict(START)
    expert = ScriptedPourPolicy()
    return {name: float(getattr(expert, name)) for name, _, _ in PARAMETERS}


def to_policy(u: np.ndarray, amount: int | None = None) -> ScriptedPourPolicy:
    """The policy of a point of the unit cube (``amount``: a known target amount)."""
    u = np.clip(np.asarray(u, float), 0.0, 1.0)
    kwargs = {name: lo + x * (hi - lo) for (name, lo, hi), x in zip(PARAMETERS, u, strict=True)}
    return ScriptedPourPolicy(**kwargs, amount=amount)


def load_search(path) -> dict:
    """A ``search.json`` written by :func:`search` (a path, or a resource with ``read_text``).

    Raises:
        InputError: the file is missing or holds no search result.
    """
    source = path if hasattr(path, "read_text") else Path(path)
    try:
        doc = json.loads(source.read_text())
        ScriptedPourPolicy(**doc["best"])
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise InputError(f"{path} is not a search.json from `pour-gym search` ({err})") from err
    return doc


def load_policy(path, amount: int | None = None) -> ScriptedPourPolicy:
    """The best policy of a ``search.json`` (``amount``: the target amount, if known)."""
    return ScriptedPourPolicy(**load_search(path)["best"], amount=amount)


def episode_returns(
    policy: ScriptedPourPolicy, env, seeds: list[int], options: dict | None = None
) -> list[dict]:
    """Run one episode per seed; the last infos with the returns."""
    out = []
    for seed in seeds:
        episode = rollout(env, policy, seed=seed, options=options)
        out.append({**episode.info, "return": episode.reward})
    return out


def score(results: list[dict], objective: str) -> float:
    """Higher is better: the mean return, or minus the mean error (spills count twice)."""
    if objective == "return":
        return float(np.mean([r["return"] for r in results]))
    errors = [
        abs(r["poured"] - r["target_amount"]) + 2 * (r["spilled"] + r["in_flight"]) for r in results
    ]
    return -float(np.mean(errors))


def score_candidate(task: dict) -> float:
    """The score of one candidate over its episodes, in an env of its own.

    A function of plain data, so that it runs the same here or as a Ray task.

    Args:
        task: ``u`` (the candidate in the unit cube; None: the ``start`` parameters),
            ``start``, ``env_kwargs``, ``seeds``,
            ``options`` (the resets'), ``objective`` and ``target_amount``.
    """
    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments

    env = gym.make(POUR_V0, **task["env_kwargs"])
    amount = task["target_amount"]
    u = task["u"]
    policy = (
        ScriptedPourPolicy(**task["start"], amount=amount)
        if u is None
        else to_policy(np.asarray(u), amount)
    )
    try:
        return score(
            episode_returns(policy, env, task["seeds"], task["options"]), task["objective"]
        )
    finally:
        env.close()


def search(
    objects="train",
    generations: int = 6,
    population: int = 6,
    episodes: int = 3,
    seed: int = 0,
    out: str | Path | None = None,
    env_kwargs: dict | None = None,
    objective: str = "return",
    target_amount: int | None = None,
    target_objects=None,
    address: str | None = None,
    start: str = "search",
    sigma: float = 0.2,
) -> dict:
    """CMA-ES over the scripted policy's parameters on Pour-v0.

    Args:
        objects: containers to search on (sources, and targets unless ``target_objects``).
        generations: CMA-ES iterations.
        population: candidates per generation.
        episodes: episodes per candidate (the same seeds for all).
        seed: seed of CMA-ES and of the episodes.
        out: folder for ``search.json`` (optional).
        env_kwargs: more Pour-v0 arguments (e.g. a smaller ``source_particles``).
        objective: "return" (mean episode return) or "error" (mean |poured - target| in
            particles, spills twice).
        target_amount: pour this many particles in every episode, and tell the policy.
        target_objects: the containers to pour into (default: ``objects``).
        address: evaluate each generation's candidates as Ray tasks there (``local``,
            ``auto`` or ``HOST:PORT``, see :mod:`pour_gym.agents.cluster`); None: one after
            another here. The result is the same either way.
        start: where the search starts (:func:`start_parameters`).
        sigma: CMA-ES's initial step, in the unit cube of the parameters' ranges.

    Returns:
        ``{"best": {param: value}, "best_score": x, "start_score": x, "objective",
        "start", "start_from", "seed", "seeds", "episodes" (in all), "wall_seconds",
        "history": [...]}`` and the containers and arguments searched on.
    """
    import cma

    if objective not in OBJECTIVES:
        raise InputError(f"objective must be one of {OBJECTIVES}, not {objective!r}")
    first = start_parameters(start)
    if not 0.0 < sigma <= 1.0:
        raise InputError(f"sigma is a step in the unit cube: (0, 1], not {sigma}")
    if generations < 1 or population < 2 or episodes < 1:
        raise InputError(
            "search needs at least 1 generation, 2 candidates and 1 episode per candidate "
            f"(got {generations}, {population}, {episodes})"
        )
    sources = list(expand_containers(objects))
    targets = list(expand_containers(target_objects)) if target_objects is not None else sources
    kwargs = dict(env_kwargs or {})
    if target_amount is not None:  # any amount the fill allows
        kwargs.setdefault("amount_range", (1, 1000))
    seeds = [seed * 1000 + k for k in range(episodes)]
    job = {
        "env_kwargs": {"source_objects": sources, "target_objects": targets, **kwargs},
        "seeds": seeds,
        "options": {"target_amount": int(target_amount)} if target_amount is not None else None,
        "objective": objective,
        "target_amount": target_amount,
        "start": first,
    }
    x0 = [(first[n] - lo) / (hi - lo) for n, lo, hi in PARAMETERS]
    es = cma.CMAEvolutionStrategy(
        x0, sigma, {"bounds": [0.0, 1.0], "popsize": population, "seed": seed + 1, "verbose": -9}
    )
    history = []
    started = time.perf_counter()
    bar = tqdm(total=generations * population + 1, desc="policy search", file=sys.stderr)
    with ray_session(address) as ray:
        start_score = map_tasks(score_candidate, [{**job, "u": None}], ray)[0]
        bar.update()
        best_score, best_u = start_score, np.array(x0)
        for g in range(generations):
            candidates = es.ask()
            tasks = [{**job, "u": list(map(float, u))} for u in candidates]
            scores = map_tasks(score_candidate, tasks, ray)
            bar.update(len(candidates))
            es.tell(candidates, [-s for s in scores])  # CMA-ES minimises
            k = int(np.argmax(scores))
            if scores[k] > best_score:
                best_score, best_u = scores[k], np.asarray(candidates[k])
            bar.set_postfix(best=f"{best_score:.3f}")
            history.append({"generation": g, "best": max(scores), "mean": float(np.mean(scores))})
    bar.close()
    best = asdict(to_policy(best_u))
    doc = {
        "sources": sources,
        "targets": targets,
        "objective": objective,
        "target_amount": target_amount,
        "episodes_per_candidate": episodes,
        "seed": seed,
        "seeds": seeds,
        "episodes": (generations * population + 1) * episodes,
        "wall_seconds": time.perf_counter() - started,
        "start": first,
        "start_from": start,
        "sigma": sigma,
        "env_kwargs": kwargs,
        "start_score": start_score,
        "best": {n: float(best[n]) for n, _, _ in PARAMETERS},
        "best_score": float(best_score),
        "history": history,
    }
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "search.json").write_text(json.dumps(doc, indent=2) + "\n")
    return doc
