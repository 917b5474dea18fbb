"""Training sweeps: a grid of ``train.py`` runs, one run directory each, on Ray Tune.

A sweep is a YAML file of :class:`~pour_gym.agents.training.TrainConfig` fields: the fixed
ones at the top level and the varied ones under ``grid:``, every combination one trial::

    env: PourGym/TiltPour-v0
    algo: ppo
    timesteps: 20000
    objects: red_cup
    eval_objects: all
    grid:
      seed: [0, 1, 2]
      obs_mode: [features, state]

Each trial trains into ``OUT/<field>-<value>_...`` (a ``train.py`` run directory: the
study report reads a sweep's output like any folder of runs). With an ``address`` the
trials are Ray Tune trials, each reserving as many CPUs as it runs environments (the
recipe's ``n_envs``; the fluid's threads follow, :func:`pour_gym.fluid.pbf.default_threads`);
without one they run here one after another. Running a sweep again re-runs only the trials
without an ``eval.json`` (an unfinished one resumes from its checkpoint).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import re
from pathlib import Path

import yaml

from pour_gym.agents.cluster import node_id, ray_session
from pour_gym.agents.training import TrainConfig, algorithm, load_recipe, train
from pour_gym.errors import InputError
from pour_gym.report.tables import markdown_table

FIELDS = {f.name for f in dataclasses.fields(TrainConfig)} - {"out"}
NODE_FILE = "node.json"


def load_spec(path: str | Path) -> tuple[dict, dict[str, list]]:
    """The fixed fields and the grid of a sweep file.

    Raises:
        InputError: no such file, unknown fields, ``out`` given, or an empty grid list.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no sweep file {str(path)!r}")
    spec = yaml.safe_load(path.read_text()) or {}
    if not isinstance(spec, dict):
        raise InputError(f"{path} must hold a mapping of TrainConfig fields and a grid:")
    grid = spec.pop("grid", {}) or {}
    if "out" in spec or "out" in grid:
        raise InputError("a sweep file does not set out: --out decides where the trials go")
    unknown = sorted((set(spec) | set(grid)) - FIELDS)
    if unknown:
        raise InputError(f"unknown fields {unknown} in {path}; known: {', '.join(sorted(FIELDS))}")
    for name, values in grid.items():
        if not isinstance(values, list) or not values:
            raise InputError(f"grid field {name!r} must be a non-empty list, not {values!r}")
    return spec, grid


def trials(fixed: dict, grid: dict[str, list], out: str | Path) -> list[TrainConfig]:
    """Every combination of the grid as a run's config, each in its own folder under ``out``."""
    names = list(grid)
    out = Path(out).resolve()  # Ray Tune runs each trial in a folder of its own
    configs = []
    for values in itertools.product(*(grid[n] for n in names)):
        varied = dict(zip(names, values, strict=True))
        label = "_".join(f"{n}-{v}" for n, v in varied.items()) or "trial"
        label = re.sub(r"[^A-Za-z0-9_.+=-]", "-", label)
        configs.append(TrainConfig(**{**fixed, **varied, "out": str(out / label)}))
    return configs


def _cpus(config: TrainConfig) -> int:
    """CPUs a trial reserves: the environments it runs (the recipe's ``n_envs``)."""
    recipe = load_recipe(
        config.env, config.algo, algorithm(config.algo), config.overrides, config.recipe
    )
    return max(recipe.n_envs, 1)


def run_trial(config: TrainConfig) -> dict:
    """Train one trial and note the Ray node it ran on (``node.json`` in its folder)."""
    result = train(config)
    where = {"node_id": node_id()}
    (Path(config.out) / NODE_FILE).write_text(json.dumps(where) + "\n")
    return result


def _tune_trial(params: dict) -> None:
    from ray import tune

    result = run_trial(TrainConfig(**params["config"]))
    tune.report({"success": float(result["mean"]["success"])})


def sweep(spec_path: str | Path, out: str | Path, address: str | None = None) -> dict:
    """Run a sweep's trials that have not finished; gather every trial's evaluation.

    Args:
        spec_path: the sweep file.
        out: the folder of the trials' run directories.
        address: a Ray address (``local``, ``auto``, ``HOST:PORT``) for Ray Tune, or None
            to train here one trial after another.

    Returns:
        ``{"trials": [{"config": {...}, "eval": {...}, "run_dir": "...", "node_id": ...}]}``
        in grid order.
    """
    fixed, grid = load_spec(spec_path)
    configs = trials(fixed, grid, out)
    pending = [c for c in configs if not (Path(c.out) / "eval.json").is_file()]
    if pending:
        with ray_session(address) as ray:
            if ray is None:
                for config in pending:
                    run_trial(config)
            else:
                from ray import tune

                Path(out).mkdir(parents=True, exist_ok=True)
                # One Tune trial per pending run; each reserves the CPUs of its environments.
                groups: dict[int, list] = {}
                for c in pending:
                    groups.setdefault(_cpus(c), []).append(dataclasses.asdict(c))
                for cpus, group in groups.items():
                    tuner = tune.Tuner(
                        tune.with_resources(_tune_trial, {"cpu": cpus}),
                        param_space={"config": tune.grid_search(group)},
                        run_config=tune.RunConfig(
                            name=f"sweep_{cpus}cpu",
                            storage_path=str(Path(out).resolve() / "_tune"),
                            verbose=0,
                        ),
                    )
                    failed = [r for r in tuner.fit() if r.error is not None]
                    if failed:
                        raise InputError(f"{len(failed)} trial(s) failed: {failed[0].error}")
    rows = []
    for config in configs:
        run_dir = Path(config.out)
        node = run_dir / NODE_FILE
        rows.append(
            {
                "config": {k: v for k, v in dataclasses.asdict(config).items() if k != "out"},
                "eval": json.loads((run_dir / "eval.json").read_text()),
                "run_dir": str(run_dir),
                "node_id": json.loads(node.read_text())["node_id"] if node.is_file() else None,
            }
        )
    return {"trials": rows}


def sweep_table(doc: dict, grid_fields: list[str]) -> str:
    """A markdown table: the varied fields, mean success and mean return per trial."""
    head = [*grid_fields, "success", "mean return", "run"]
    rows = []
    for trial in doc["trials"]:
        mean = trial["eval"]["mean"]
        cells = [str(trial["config"][f]) for f in grid_fields]
        cells += [f"{mean['success']:.2f}", f"{mean['return']:.2f}", trial["run_dir"]]
        rows.append(cells)
    return markdown_table(head, rows, align="l" * len(head))
