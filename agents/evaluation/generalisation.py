"""The generalisation study: warped features against raw state on unseen containers.

The same agent is trained on the red cup with the warped features or with raw state and
evaluated on containers it never saw.

:func:`study_report` gathers ``train.py`` run directories (each with ``config.json`` and
``eval.json``) into one markdown report with a table and a bar chart per environment. For
Pour-v0 it also evaluates every run on the matrix of sources and targets (the nine thesis
objects, each as both; cached as ``matrix.json`` in the run directory) and draws the
matrices as heat maps.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pour_gym.envs import POUR_V0
from pour_gym.errors import InputError
from pour_gym.report.tables import markdown_table


def _load_runs(roots: list[Path]) -> dict[str, dict[str, list[dict]]]:
    """Every run directory under the roots: ``{env: {obs_mode: [run, ...]}}``.

    The runs of one environment and observation mode (seeds, e.g. a sweep's) are a list,
    by seed: the report shows their mean and spread, none overwrites another.
    """
    runs: dict[str, dict[str, list[dict]]] = {}
    for root in roots:
        for eval_path in sorted(root.glob("*/eval.json")):
            config = json.loads((eval_path.parent / "config.json").read_text())
            runs.setdefault(config["env"], {}).setdefault(config["obs_mode"], []).append(
                {
                    "config": config,
                    "eval": json.loads(eval_path.read_text()),
                    "dir": eval_path.parent,
                }
            )
    if not runs:
        raise InputError(
            f"no runs under {', '.join(map(str, roots))} (train.py run directories with "
            "eval.json; run docs/generalisation/run.sh first)"
        )
    for modes in runs.values():
        for group in modes.values():
            group.sort(key=lambda r: (r["config"].get("seed", 0), str(r["dir"])))
    return runs


def _success(group: list[dict]) -> dict[str, np.ndarray]:
    """Each container's success in each run of a group: ``{object: array over runs}``."""
    table: dict[str, list[float]] = {}
    for run in group:
        for r in run["eval"]["rows"]:
            table.setdefault(r["object"], []).append(r["success"])
    return {name: np.asarray(values) for name, values in table.items()}


def _cell(values: np.ndarray) -> str:
    """Mean success, with the spread over seeds when there are several."""
    if len(values) == 1:
        return f"{values[0]:.2f}"
    return f"{values.mean():.2f} ± {values.std(ddof=1):.2f}"


def _trained(config: dict) -> str:
    """How a run was trained, in words."""
    from pour_gym.assets import expand_containers

    objects = ", ".join(expand_containers(config["objects"]))
    algo, steps, seed = config["algo"].upper(), config["timesteps"], config["seed"]
    return f"{algo}, {steps} steps, seed {seed}, on {objects}"


def _plot(env: str, modes: dict[str, list[dict]], path: Path) -> Path:
    """Bars of the mean success per container and mode; the spread over seeds as error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = next(iter(modes.values()))[0]["eval"]["rows"]
    names = [r["object"] for r in rows]
    trained = [r["trained_on"] for r in rows]
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.8 / len(modes)
    for k, (mode, group) in enumerate(sorted(modes.items())):
        success = _success(group)
        means = [success[n].mean() if n in success else 0.0 for n in names]
        spread = [success[n].std(ddof=1) if n in success and len(success[n]) > 1 else 0.0
                  for n in names]  # fmt: skip
        label = f"obs_mode={mode}" + (f" ({len(group)} seeds)" if len(group) > 1 else "")
        ax.bar(x + (k - (len(modes) - 1) / 2) * width, means, width, yerr=spread, label=label,
               capsize=2)  # fmt: skip
    labels = [n + (" *" if t else "") for n, t in zip(names, trained, strict=True)]
    ax.set_xticks(x, labels, rotation=35, ha="right", fontsize=8)
    ax.set_ylabel("success rate")
    ax.set_ylim(0, 1.05)
    ax.set_title(f"{env}: trained on the containers marked *, evaluated on every container")
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def pour_matrix(run_dir: Path, episodes: int = 2, objects: tuple[str, ...] | None = None) -> dict:
    """Pour-v0 success and amount error of a run's model for every source and target.

    Cached as ``matrix.json`` in the run directory (recomputed when the episodes differ).
    """
    from pour_gym.agents.evaluation.evaluate import evaluate_policy
    from pour_gym.agents.policies.rollout import sb3_policy
    from pour_gym.agents.training import load_run
    from pour_gym.objects import OBJECT_NAMES

    objects = tuple(objects or OBJECT_NAMES)
    cache = run_dir / "matrix.json"
    if cache.is_file():
        doc = json.loads(cache.read_text())
        if doc.get("episodes") == episodes and tuple(doc.get("objects", ())) == objects:
            return doc
    run = load_run(run_dir / "model.zip")
    result = evaluate_policy(
        sb3_policy(run),
        POUR_V0,
        episodes=episodes,
        env_kwargs=run.env_kwargs(),
        trained_on=run.trained_on(),
        source_objects=objects,
        target_objects=objects,
    )
    doc = {"episodes": episodes, "objects": list(objects), **result}
    cache.write_text(json.dumps(doc, indent=2) + "\n")
    return doc


def _matrix_plot(matrices: dict[str, dict], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(matrices), figsize=(6.5 * len(matrices), 6), squeeze=False)
    for k, (ax, (mode, doc)) in enumerate(zip(axes[0], sorted(matrices.items()), strict=True)):
        names = doc["objects"]
        grid = np.zeros((len(names), len(names)))
        for r in doc["rows"]:
            grid[names.index(r["source"]), names.index(r["target"])] = r["success"]
        im = ax.imshow(grid, vmin=0, vmax=1, cmap="viridis")
        ax.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
        ax.set_xlabel("target")
        # The panels share their sources: only the first names them (the others' labels
        # ran into the panel beside).
        ax.set_yticks(range(len(names)), names if k == 0 else [], fontsize=7)
        if k == 0:
            ax.set_ylabel("source")
        ax.set_title(f"obs_mode={mode}: success per pair ({doc['episodes']} episodes)")
        for i in range(len(names)):
            for j in range(len(names)):
                ax.text(j, i, f"{grid[i, j]:.1f}", ha="center", va="center", fontsize=6,
                        color="white" if grid[i, j] < 0.5 else "black")  # fmt: skip
    fig.colorbar(im, ax=axes[0].tolist(), shrink=0.7, label="success rate")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def study_report(
    runs_dir: str | Path | list[str | Path], out: str | Path, matrix_episodes: int = 2
) -> dict:
    """Write ``report.md`` and plots; returns the numbers.

    Args:
        runs_dir: folder(s) of ``train.py`` run directories (a comma-separated string too).
        out: folder for the report and its pictures.
        matrix_episodes: Pour-v0 episodes per (source, target) pair.

    Returns:
        ``{env: {mode: {"trained": success on the training containers, "unseen": mean
        success on the others, ...}}}``.
    """
    from pour_gym.assets import expand_containers

    if isinstance(runs_dir, str | Path):
        roots = [Path(p) for p in str(runs_dir).split(",")]
    else:
        roots = [Path(p) for p in runs_dir]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs = _load_runs(roots)
    summary: dict = {}
    lines = [
        "# Generalisation: warped features against raw state",
        "",
        "Agents trained on the containers marked in each table, once with the warped",
        "high-level features as observations and once with raw state (positions and",
        "bounding-box sizes, no labels), then evaluated on containers they never saw.",
        "Success is the fraction of successful episodes per container (seeds fixed in",
        "`train.py`'s evaluation, never used in training).",
        "",
        "Reproduce: `sh docs/generalisation/run.sh` (the one-step environments) and the",
        "headline Pour-v0 runs in docs/learning.md.",
        "",
    ]
    for env, modes in sorted(runs.items()):
        summary[env] = {}
        ordered = sorted(modes)
        lines += [f"## {env}", ""]
        for m in ordered:
            group = modes[m]
            seeds = [g["config"].get("seed") for g in group]
            what = _trained(group[0]["config"])
            if len(group) > 1:
                what = what.replace(f"seed {seeds[0]}", f"seeds {', '.join(map(str, seeds))}")
            lines.append(
                f"- `{m}`: {what}; {group[0]['eval']['episodes']} evaluation episodes per "
                "container" + (" per seed (mean ± standard deviation over seeds)"
                               if len(group) > 1 else "")
            )  # fmt: skip
        rows = []
        success = {m: _success(modes[m]) for m in ordered}
        seen = {r["object"]: r["trained_on"] for r in modes[ordered[0]][0]["eval"]["rows"]}
        for name, was_trained in seen.items():
            cells = [_cell(success[m][name]) if name in success[m] else "" for m in ordered]
            mark = " (trained)" if was_trained else ""
            rows.append([f"{name}{mark}", *cells])
        for m in ordered:
            unseen = [success[m][n] for n, t in seen.items() if not t and n in success[m]]
            trained = [success[m][n] for n, t in seen.items() if t and n in success[m]]
            # Per seed: the mean over the unseen containers; then mean and spread of those.
            per_seed = np.mean(unseen, axis=0) if unseen else None
            summary[env][m] = {
                "trained": float(np.mean(trained)) if trained else None,
                "unseen": float(np.mean(per_seed)) if unseen else None,
                "seeds": [g["config"].get("seed") for g in modes[m]],
                "unseen_per_seed": per_seed.tolist() if unseen else None,
                "unseen_std": float(np.std(per_seed, ddof=1))
                if unseen and len(per_seed) > 1
                else None,
            }
        rows.append([
            "mean over unseen",
            *(_cell(np.atleast_1d(summary[env][m]["unseen_per_seed"]))
              if summary[env][m]["unseen"] is not None else "" for m in ordered),
        ])  # fmt: skip
        lines += ["", markdown_table(["container", *ordered], rows)]
        png = _plot(env, modes, out / f"{env.split('/')[-1]}.png")
        lines += ["", f"![{env}]({png.name})", ""]
        if env == POUR_V0:
            # The matrix is one run's per mode (the first seed's): it costs 81 pairs of
            # episodes per run.
            matrices = {m: pour_matrix(modes[m][0]["dir"], matrix_episodes) for m in ordered}
            heat = _matrix_plot(matrices, out / "Pour-v0-matrix.png")
            lines += [
                "### Every source into every target",
                "",
                f"Each of the nine thesis objects as the source and as the target, "
                f"{matrix_episodes} episodes per pair.",
                "",
            ]
            rows = []
            for m in ordered:
                doc = matrices[m]
                seen_objects = set(expand_containers(modes[m][0]["config"]["objects"]))
                both = [r["success"] for r in doc["rows"]
                        if r["source"] not in seen_objects
                        and r["target"] not in seen_objects]  # fmt: skip
                summary[env][m]["matrix"] = {
                    "success": doc["mean"]["success"],
                    "success_unseen_pairs": float(np.mean(both)) if both else None,
                    "amount_error": doc["mean"]["amount_error"],
                    "spilled": doc["mean"]["spilled"],
                }
                s = summary[env][m]["matrix"]
                rows.append([m, f"{s['success']:.2f}", f"{s['success_unseen_pairs']:.2f}",
                             f"{s['amount_error']:.1f}", f"{s['spilled']:.2f}"])  # fmt: skip
            header = ["obs_mode", "success over all pairs",
                      "success, source and target both unseen",
                      "mean amount error (particles)", "mean spilled"]  # fmt: skip
            lines += [markdown_table(header, rows)]
            lines += ["", f"![success per source and target]({heat.name})", ""]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary
