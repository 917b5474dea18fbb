"""What the baselines report keeps of a run or a reference evaluation: its summary.

A summary (:func:`run_summary`, :func:`run_summaries`, :func:`reference_summary`) is a
small dict: the run's recipe, how it learnt, which model was evaluated and how it acted,
its evaluation's rows and means, its learning curve and its wall time.
:mod:`pour_gym.agents.evaluation.baselines` writes the report from them.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np

from pour_gym.errors import InputError

SAMPLED = ", sampled actions"  # a model kind's suffix: scored by its samples, not its mean


def training_kind(config: dict) -> str:
    """How a run learnt.

    ``"reward"``, ``"clone"`` (cloning only), ``"clone + RL"``, or ``"reward, residual on
    the expert"`` (a correction to the scripted expert's actions, learnt from the reward).
    """
    if config.get("residual"):
        return "reward, residual on the expert"
    if not config.get("demonstrations"):
        return "reward"
    steps = config.get("hyperparameters", {}).get("gradient_steps", 1)
    return "clone" if steps == 0 else "clone + RL"


def recipe_name(config: dict) -> str:
    """The run's ``agents/hyperparams.yaml`` recipe as the report names it.

    ``"family-schedule"``, followed by ``" + 2 --set"`` where the run overrode arguments of
    it and by the env arguments given with ``--env-kwargs`` (``", time_weight=0.004"``;
    the observation is a column of its own); ``"-"`` for a run trained without one.
    """
    recipe = config.get("recipe") or "-"
    overrides = config.get("overrides") or {}
    env = {k: v for k, v in (config.get("env_kwargs") or {}).items() if k != "obs_mode"}
    given = "".join(f", {k}={v}" for k, v in sorted(env.items()))
    return recipe + (f" + {len(overrides)} --set" if overrides else "") + given


def model_kind(config: dict) -> str:
    """Which of a run's models was evaluated, and how it acted.

    ``"last step"`` or, for a run with ``--keep-best``, ``"best curve point"``; with
    ``--stochastic-eval``, followed by ``", sampled actions"`` (the policy's samples, not
    its mean action).
    """
    which = "best curve point" if config.get("keep_best") else "last step"
    return which + (SAMPLED if config.get("stochastic_eval") else "")


def _wall_seconds(run_dir: Path, result: dict) -> float | None:
    """A run's training wall time, s.

    Its last process's (``eval.json``) plus, for a resumed run, the learning loops of the
    parts before (``progress_until_*.csv``). None for a run from before ``eval.json``
    recorded it (SB3's ``progress.csv`` times the learning loop alone, not the cloning
    before it).
    """
    if "train_seconds" not in result:
        return None
    total = float(result["train_seconds"])
    for part in run_dir.glob("progress_until_*.csv"):
        with open(part, newline="") as fh:
            times = [float(r["time/time_elapsed"]) for r in csv.DictReader(fh)
                     if r.get("time/time_elapsed")]  # fmt: skip
        total += times[-1] if times else 0.0
    return total


def eval_metrics(rows: list[dict]) -> dict[str, float | None]:
    """The report's metrics of one evaluation's rows (None where a group is empty)."""
    trained = [r for r in rows if r["trained_on"]]
    unseen = [r for r in rows if not r["trained_on"]]

    def mean(group: list[dict], key: str) -> float | None:
        return float(np.mean([r[key] for r in group])) if group else None

    return {
        "trained_success": mean(trained, "success"),
        "unseen_success": mean(unseen, "success"),
        "unseen_amount_error": mean(unseen, "amount_error"),
        "unseen_spilled": mean(unseen, "spilled"),
    }


def scored_on(rows: list[dict]) -> str:
    """What a summary's unseen metrics are over, as the report's column says it.

    ``"procedural:test (100)"`` when every unseen container is a member of one family,
    ``"catalogue (11)"`` when every one is a catalogue container, ``"user meshes (2)"``
    when every one is a user's file, else the kinds joined (``"catalogue + user meshes
    (14)"``): how many containers, and which kind.
    """
    from pour_gym.assets import CATALOGUE

    unseen = sorted({r["object"] for r in rows if not r["trained_on"]})
    families = {name.split("#")[0] for name in unseen if "#" in name}
    if len(families) == 1 and all("#" in name for name in unseen):
        return f"{families.pop()} ({len(unseen)})"
    kinds = []
    if any("#" in name for name in unseen):
        kinds.append(" + ".join(sorted(families)))
    if any(name in CATALOGUE for name in unseen):
        kinds.append("catalogue")
    # Neither a member nor a catalogue name: a mesh file or asset folder of the user's.
    if any("#" not in name and name not in CATALOGUE for name in unseen):
        kinds.append("user meshes")
    return f"{' + '.join(kinds)} ({len(unseen)})"


def run_summary(run_dir: Path) -> dict:
    """The summary of one ``train.py`` run directory (config.json and eval.json in it).

    Raises:
        InputError: a folder that is not a finished run.
    """
    from pour_gym.agents.training.curves import read_curve

    run_dir = Path(run_dir)
    paths = {name: run_dir / f"{name}.json" for name in ("config", "eval")}
    missing = [str(p) for p in paths.values() if not p.is_file()]
    if missing:
        raise InputError(f"{run_dir} is not a finished train.py run: {', '.join(missing)} missing")
    config = json.loads(paths["config"].read_text())
    result = json.loads(paths["eval"].read_text())
    rows = result["rows"]
    curve = read_curve(run_dir / "curve.csv")
    return {
        "run": run_dir.name,
        "env": config["env"],
        "algo": config["algo"],
        "obs_mode": config["obs_mode"],
        "kind": training_kind(config),
        "recipe": recipe_name(config),
        "model": model_kind(config),
        # Exploration other than the algorithm's own Gaussian noise (a row of its own).
        "exploration": "gSDE" if config.get("hyperparameters", {}).get("use_sde") else "",
        "seed": config["seed"],
        "timesteps": config["timesteps"],
        "wall_seconds": _wall_seconds(run_dir, result),
        "objects": config["objects"],
        "env_kwargs": config.get("env_kwargs", {}),
        "metrics": eval_metrics(rows),
        "eval_episodes": result["episodes"],
        "eval_rows": rows,
        "curve": {k: v.tolist() for k, v in curve.items()} if curve is not None else None,
    }


def read_evaluation(path: Path, hint: str) -> dict:
    """An evaluation's JSON (``pour-gym evaluate ... --json``): its env, episodes and rows.

    Raises:
        InputError: a file that is not one, named, with ``hint`` (how to write one).
    """
    try:
        result = json.loads(Path(path).read_text())
        if not (
            isinstance(result["env"], str)
            and isinstance(result["episodes"], int)
            and all(isinstance(r, dict) and "object" in r for r in result["rows"])
        ):
            raise TypeError
    except (OSError, ValueError, KeyError, TypeError):
        raise InputError(f"{path} is not an evaluation: {hint}") from None
    return result


def run_summaries(run_dir: Path) -> list[dict]:
    """The summaries of one run: its own evaluation's, then one per further evaluation.

    A further evaluation is an ``eval-<name>.json`` in the run directory, written by
    ``pour-gym evaluate <run_dir> ... --json`` (for example a family run scored on the
    catalogue too, or with ``--actions sampled``); its summary is the run's with that
    evaluation's rows, named ``<run>-<name>``: another row of the report (other unseen
    containers, or the model acting otherwise), the same training (curve, wall time). One
    of a checkpoint (``pour-gym evaluate <run_dir>/checkpoints/model_N_steps.zip``) is the
    model "checkpoint at N steps", its env steps N and its wall time not known.

    Raises:
        InputError: a folder that is not a finished run, or a further evaluation that is
            not an evaluation's JSON.
    """
    main = run_summary(run_dir)
    found = [main]
    for path in sorted(Path(run_dir).glob("eval-*.json")):
        result = read_evaluation(
            path,
            f"write it with `pour-gym evaluate {run_dir} --objects all,real --episodes 10 "
            f"--seed 10000 --json > {path}`",
        )
        rows, episodes = result["rows"], result["episodes"]
        name = path.stem.removeprefix("eval-")
        model, timesteps, wall = main["model"], main["timesteps"], main["wall_seconds"]
        # A checkpoint of the run (pour-gym evaluate RUN/checkpoints/model_N_steps.zip):
        # its own steps, not the run's end; its share of the wall time is not recorded.
        from pour_gym.agents.training.runs import checkpoint_steps

        checkpoint = checkpoint_steps(result.get("policy", ""))
        if checkpoint is not None:
            timesteps, wall = checkpoint, None
            model = f"checkpoint at {timesteps:,} steps"
        if result.get("actions"):  # evaluated by its mean or its samples, whatever in training
            model = model.removesuffix(SAMPLED) + (
                SAMPLED if result["actions"] == "sampled" else ""
            )
        # Evaluated with environment arguments of its own (pour-gym evaluate --env-kwargs):
        # a row of its own, its returns in those arguments' units (no aggregates with
        # reward weights of its own, as for a run trained under them).
        extra = result.get("env_kwargs") or {}
        if extra:
            model += ", " + ", ".join(f"{k}={v}" for k, v in sorted(extra.items()))
        found.append({**main, "run": f"{main['run']}-{name}", "model": model,
                      "timesteps": timesteps, "wall_seconds": wall,
                      "env_kwargs": {**main["env_kwargs"], **extra},
                      "metrics": eval_metrics(rows), "eval_episodes": episodes,
                      "eval_rows": rows})  # fmt: skip
    return found


# What a reference row's evaluation was of (``pour-gym evaluate <policy> --json``): its
# run's name's start, its algorithm column and how it learnt.
REFERENCES = {
    "scripted": ("scripted-expert", "scripted", "hand-written (reference)"),
    "random": ("random", "random", "uniform random (reference)"),
}


def reference_summary(eval_path: Path, trained_on: tuple[str, ...] = ("red_cup",)) -> dict:
    """A reference row from ``pour-gym evaluate scripted --json`` (or ``random``).

    The expert the runs are measured against, or the seeded random policy a normalised
    score calls 0, on the same containers and seeds as their evaluations. Its rows for
    ``trained_on`` (the runs' training container) count as "trained on", the others as
    unseen: its unseen means are over the runs' unseen ones.

    Raises:
        InputError: a file that is not an evaluation's JSON.
    """
    result = read_evaluation(
        eval_path,
        "write one with `pour-gym evaluate scripted --objects all,real --episodes 10 "
        "--seed 10000 --json` (or random)",
    )
    policy = result.get("policy", "scripted")
    if policy not in REFERENCES:
        raise InputError(
            f"{eval_path} evaluates {policy!r}: a reference row is the scripted expert's or "
            "the random policy's (pour-gym evaluate scripted|random --json)"
        )
    prefix, algo, kind = REFERENCES[policy]
    rows = [{**r, "trained_on": r["object"] in trained_on} for r in result["rows"]]
    env = result["env"]
    where = scored_on(rows)
    # One reference per env and set of containers: the catalogue's keeps its old name.
    kind_of = where.rsplit(" (", 1)[0]
    suffix = "" if kind_of == "catalogue" else "-" + re.sub(r"[^a-z0-9]+", "-", kind_of.lower())
    return {
        "run": f"{prefix}-{env.split('/')[-1].lower()}{suffix}",
        "env": env,
        "algo": algo,
        "obs_mode": "features" if algo == "scripted" else "-",
        "kind": kind,
        "recipe": "-",
        "model": "deterministic" if algo == "scripted" else "seeded per episode",
        "seed": 0,
        "timesteps": 0,
        "wall_seconds": None,
        "objects": "",
        "env_kwargs": {},
        "metrics": eval_metrics(rows),
        "eval_episodes": result["episodes"],
        "eval_rows": rows,
        "curve": None,
    }
