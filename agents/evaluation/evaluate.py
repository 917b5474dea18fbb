"""Evaluating a policy on every container: success rate, amount error and spill per object.

A policy is anything that maps an observation to an action (see
:mod:`pour_gym.agents.policies.rollout`): an SB3 model, the scripted policy, or a parameterised
policy from policy search. Objects the policy never trained on are marked, which is the
generalisation the thesis argues for. For the pouring tasks the rows are (source, target) pairs:
each object as both (the default), or every source with every target (a matrix).
"""

from __future__ import annotations

import copy
import itertools
import sys
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from pour_gym.agents.evaluation.shapes import shape_section
from pour_gym.agents.policies.rollout import SampledPolicy, rollout
from pour_gym.envs import make, mean_metrics, task_of
from pour_gym.errors import InputError
from pour_gym.report.tables import markdown_table


@dataclass
class LoadedPolicy:
    """A policy ready to evaluate, with the environment it acts in.

    Attributes:
        policy: observation -> action.
        env_id: the environment id it acts in.
        env_kwargs: the environment arguments it needs (a model's observation mode, ...).
        trained_on: the containers it was trained (or searched) on.
    """

    policy: Callable[[np.ndarray], np.ndarray]
    env_id: str
    env_kwargs: dict = field(default_factory=dict)
    trained_on: list[str] = field(default_factory=list)


def load_policy(
    name: str,
    env_id: str | None = None,
    algo: str | None = None,
    actions: str | None = None,
    env_kwargs: dict | None = None,
) -> LoadedPolicy:
    """A policy by name: ``"scripted"``, ``"random"``, a search's ``search.json``, or a model.

    Args:
        name: ``"scripted"``, ``"random"`` (uniform actions, seeded per episode: the
            reference of a normalised score's 0), a ``search.json``, a shipped model's name
            (``pour-v0-red-cup-features``) or a ``model.zip``.
        env_id: the environment (default: the model's, or Pour-v0 for the scripted ones).
        algo: the algorithm of a model without a ``config.json``.
        actions: a model's ``"mean"`` action or its ``"sampled"`` ones (seeded per
            episode); None: as its run scored it (``stochastic_eval`` in its config).
        env_kwargs: the arguments the env will be made with: the scripted policy acts in
            their action form (``tilt_control``, ``max_tilt_rate``, ...), not the id's.

    Raises:
        InputError: an unknown policy, a scripted policy for an env that does not pour, or
            a model asked to act in another env than it was trained on.
    """
    from pour_gym.agents.policies.rollout import sb3_policy
    from pour_gym.envs import POUR_V0

    if actions not in (None, "mean", "sampled"):
        raise InputError(f"actions are 'mean' or 'sampled', not {actions!r}")
    if name == "random":
        from pour_gym.agents.policies.rollout import RandomPolicy

        if actions is not None:
            raise InputError("--actions is for a trained model; the random policy has none")
        env_id = env_id or POUR_V0
        env = make(env_id)
        space = env.action_space
        env.close()
        return LoadedPolicy(RandomPolicy(space.low, space.high), env_id)
    if name == "scripted" or name.endswith(".json"):
        if actions is not None:
            raise InputError("--actions is for a trained model; the scripted policy has no noise")
        from pour_gym.agents.policies.scripted import ScriptedPourPolicy, action_settings
        from pour_gym.agents.policies.search import load_search

        env_id = env_id or POUR_V0
        try:
            pours = task_of(env_id).pours
        except ValueError as exc:
            raise InputError(str(exc)) from None
        if not pours:
            raise InputError(
                f"the scripted policy pours from a source into a target, not in {env_id}"
            )
        settings = action_settings(env_id, env_kwargs)
        if name == "scripted":
            return LoadedPolicy(ScriptedPourPolicy(**settings), env_id)
        found = load_search(name)  # the best of a policy search, on the containers it searched
        return LoadedPolicy(
            ScriptedPourPolicy(**found["best"], **settings), env_id,
            trained_on=list(found.get("sources", [])),
        )  # fmt: skip
    from pour_gym.agents.training.runs import load_run

    run = load_run(name, algo)
    env_id = env_id or run.config.get("env") or POUR_V0
    if run.config.get("env") and run.config["env"] != env_id:
        raise InputError(f"the model was trained on {run.config['env']}, not {env_id}")
    deterministic = None if actions is None else actions == "mean"
    return LoadedPolicy(sb3_policy(run, deterministic), env_id, run.env_kwargs(), run.trained_on())


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
    workers: int = 1,
) -> dict:
    """Run ``episodes`` episodes per object (or per source-target pair) and summarise them.

    Args:
        policy: observation -> action (``reset()`` called at every episode if it has one).
        env_id: a registered ``PourGym/`` id.
        objects: containers (names or mesh paths); for a pouring task each is the source
            and the target of its row.
        episodes: episodes per row.
        seed: seed of the first episode (row k, episode e uses ``seed + k * episodes + e``).
        env_kwargs: more keyword arguments for ``gymnasium.make``.
        trained_on: objects the policy was trained on (marked in the rows).
        source_objects: a pouring task: sources of a matrix of rows (with
            ``target_objects``).
        target_objects: a pouring task: targets of a matrix of rows (default: ``objects``).
        workers: rows evaluated at once, each in a thread of this process with an env and a
            copy of the policy of its own. The fluid's kernel runs without Python's lock,
            so two workers keep two cores busy; each row's episodes, and so the result,
            are the same for any number of workers.

    Raises:
        InputError: ``workers`` below 1, or above 1 for a policy that samples its actions
            (they come from torch's one global generator, which threads would share).

    Returns:
        ``{"env", "episodes", "seed", "rows": [{"object", "source", "target", "trained_on", and
        the task's metrics and diagnostics (:class:`pour_gym.envs.task.Task`: "success",
        "return", and for a pouring task "amount_error", "spilled", "corrections"), each
        the mean over the row's episodes; for a pouring task its profile, "pour_seconds"
        and "peak_flow" (:func:`pour_gym.envs.task.pour_profile`), likewise, and the share
        of its episodes per outcome, ``outcome_<name>`` (:meth:`~pour_gym.envs.task.Task.outcome`:
        why an episode failed)}...], "mean": {the means over the rows}}``; ``target`` is
        None for the one-container tasks.
    """
    task = task_of(env_id)
    objects = list(objects)
    if source_objects is not None or target_objects is not None:
        if not task.pours:
            raise ValueError(f"sources and targets are for the pouring tasks, not {env_id}")
        sources = list(source_objects if source_objects is not None else objects)
        targets = list(target_objects if target_objects is not None else objects)
        pairs = list(itertools.product(sources, targets))
    else:
        pairs = [(name, name) for name in objects]
    if not pairs:
        raise ValueError("no containers to evaluate on")
    workers = int(workers)
    if workers < 1:
        raise InputError(
            f"workers is how many rows are evaluated at once, 1 or more, not {workers}"
        )
    if workers > 1 and samples(policy):
        raise InputError(
            "a policy that samples its actions draws them from torch's global generator, "
            "which threads would share: evaluate it with one worker (workers=1)"
        )
    trained = set(trained_on)
    bar = tqdm(total=len(pairs) * episodes, desc=f"evaluate {env_id}", file=sys.stderr)

    def row(k: int) -> dict:
        source, target = pairs[k]
        if task.pours:
            containers = {"source_objects": [source], "target_objects": [target]}
        else:
            containers = {"objects": [source]}
        # With workers, each row's fluid on one thread (its particles are the same on any
        # number), unless the caller chose.
        threads = {"num_threads": 1} if workers > 1 else {}
        env = make(env_id, **containers, **{**threads, **(env_kwargs or {})})
        # A row of its own: a policy's state (the expert's flow estimate) is per episode.
        acting = copy.deepcopy(policy) if workers > 1 else policy
        metrics, last = [], []
        for ep in range(episodes):  # the bar counts episodes, as its total does
            episode = rollout(env, acting, seed=seed + k * episodes + ep, keep_infos=task.pours)
            metrics.append(
                {
                    **episode.metrics(task),
                    **task.diagnostics(episode.info),
                    **task.profile(episode.infos, env.unwrapped.dt),
                }
            )
            last.append(episode.info)
            bar.update()
        env.close()
        return {
            "object": source if source == target else f"{source} -> {target}",
            "source": source,
            "target": target if task.pours else None,
            "trained_on": source in trained and (target in trained or not task.pours),
            **mean_metrics(metrics),
            **task.outcome_shares(last),
        }

    if workers == 1:
        rows = [row(k) for k in range(len(pairs))]
    else:
        with ThreadPoolExecutor(min(workers, len(pairs)), "pour-gym evaluate") as pool:
            rows = list(pool.map(row, range(len(pairs))))
    bar.close()
    profile = ("pour_seconds", "peak_flow") if task.pours else ()
    keys = (*task.metric_names, *profile, *(f"outcome_{name}" for name in task.outcomes))
    mean = mean_metrics({key: r[key] for key in keys} for r in rows)
    unseen = [r for r in rows if not r["trained_on"]]
    if unseen and len(unseen) < len(rows):
        mean["success_unseen"] = float(np.mean([r["success"] for r in unseen]))
    return {"env": env_id, "episodes": episodes, "seed": seed, "rows": rows, "mean": mean}


def samples(policy: Callable) -> bool:
    """Whether a policy samples its actions (alone, or as a residual's learner)."""
    return isinstance(policy, SampledPolicy) or isinstance(
        getattr(policy, "learner", None), SampledPolicy
    )


def evaluation_table(result: dict) -> str:
    """Markdown table of :func:`evaluate_policy` (objects trained on marked with *)."""
    pours = task_of(result["env"]).pours
    header = ["object", "success", "mean return"]
    if pours:
        header += ["mean amount error (particles)", "mean spilled", "pour, s", "peak flow, T/s",
                   "failures"]  # fmt: skip
    rows = []
    for r in result["rows"]:
        row = [r["object"] + (" *" if r["trained_on"] else ""), f"{r['success']:.2f}",
               f"{r['return']:.2f}"]  # fmt: skip
        if pours:
            row += [f"{r['amount_error']:.1f}", f"{r['spilled']:.1f}", *_profile(r), failures_of(r)]
        rows.append(row)
    m = result["mean"]
    last = ["**mean**", f"**{m['success']:.2f}**", f"{m['return']:.2f}"]
    if pours:
        last += [f"{m['amount_error']:.1f}", f"{m['spilled']:.2f}", *_profile(m), failures_of(m)]
    lines = [markdown_table(header, [*rows, last], align="l" + "r" * (len(header) - 1))]
    if "success_unseen" in m:
        lines.append(f"\nsuccess on containers never trained on: {m['success_unseen']:.2f}")
    if pours:
        lines.append(
            "\npour: how long the stream ran; peak flow: the most that left the source in one "
            "step, in target amounts per second (envs.task.pour_profile)"
        )
        lines.append(
            "\nfailures: the share of episodes that failed, by why (envs.rules.POUR_OUTCOMES)"
        )
    lines.append("\n\\* trained on this object")
    shapes = shape_section(result) if pours else None
    if shapes:
        lines.append("\n" + shapes)
    return "\n".join(lines)


def liquids_table(result: dict) -> str:
    """Markdown of an evaluation over liquids: a row per liquid, then each one's table.

    ``result["by_liquid"]`` maps each liquid's name to an :func:`evaluate_policy` result.
    """
    pours = task_of(result["env"]).pours
    header = ["liquid", "success", "mean return"]
    if pours:
        header += ["mean amount error (particles)", "mean spilled", "pour, s", "peak flow, T/s",
                   "failures"]  # fmt: skip
    rows = []
    for name, res in result["by_liquid"].items():
        m = res["mean"]
        row = [name, f"{m['success']:.2f}", f"{m['return']:.2f}"]
        if pours:
            row += [f"{m['amount_error']:.1f}", f"{m['spilled']:.2f}", *_profile(m), failures_of(m)]
        rows.append(row)
    parts = [markdown_table(header, rows, align="l" + "r" * (len(header) - 1))]
    for name, res in result["by_liquid"].items():
        parts.append(f"\n### {name}\n\n{evaluation_table(res)}")
    return "\n".join(parts)


def _profile(row: dict) -> list[str]:
    """A row's pour time (s) and peak flow (T/s); ``-`` for results from before them."""
    if "pour_seconds" not in row:
        return ["-", "-"]
    return [f"{row['pour_seconds']:.1f}", f"{row['peak_flow']:.2f}"]


def failures_of(row: dict) -> str:
    """A row's failed episodes by outcome, e.g. ``spilled 0.2, overshot 0.1``.

    Results from before outcomes were recorded give ``-``.
    """
    shares = [
        (key.removeprefix("outcome_"), value)
        for key, value in row.items()
        if key.startswith("outcome_") and key != "outcome_success" and value > 0
    ]
    if not any(key.startswith("outcome_") for key in row):
        return "-"
    return ", ".join(f"{name} {value:.2f}" for name, value in shares) or "none"
