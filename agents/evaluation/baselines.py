"""The baselines report: algorithms x observation modes, several seeds, intervals over seeds.

``pour-gym report baselines --runs DIR...`` reads ``train.py`` run directories, keeps one
small summary per run (``docs/baselines/runs/<run>.json``: the run's recipe, its
evaluation, its learning curve, its wall time) and writes ``docs/baselines.md`` and
``docs/baselines/curves.png`` from every summary there. The summaries are what is
committed: the report can be regenerated from them without the run directories (their
checkpoints and replay buffers are hundreds of MB).

A row is one way of training (environment, algorithm, the ``agents/hyperparams.yaml``
recipe, observation mode, whether it learnt from the reward alone, cloned the expert, or
cloned then learnt, which model of a run was evaluated: the last step's or, with
``--keep-best``, the best curve point's, what it trained on and which unseen containers
it was scored on): its seeds' mean of each metric, with a 95 % bootstrap interval over
the seeds, and over the seeds and the unseen containers, rliable's aggregates
(:mod:`pour_gym.agents.evaluation.aggregate`): the interquartile mean of the return
normalised between a seeded random policy (0) and the scripted expert (1) on the same
episodes, and the probability that a seed beats the expert on a container, each with a
stratified-bootstrap interval.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from pour_gym.agents.evaluation.aggregate import (
    bootstrap_interval,
    iqm,
    mean_interval,
    normalised,
    probability_of_improvement,
)
from pour_gym.agents.evaluation.summaries import (
    REFERENCES,
    eval_metrics,
    reference_summary,
    run_summaries,
    scored_on,
)
from pour_gym.errors import InputError
from pour_gym.report.tables import markdown_table

SUMMARIES = Path("docs/baselines/runs")
REPORT = Path("docs/baselines.md")
CURVES = Path("docs/baselines/curves.png")
METRICS = {
    "trained_success": "success, trained on",
    "unseen_success": "success, unseen",
    "unseen_amount_error": "amount error, unseen (particles)",
    "unseen_spilled": "spilled, unseen (particles)",
}


def _unseen(summary: dict) -> frozenset[str]:
    return frozenset(r["object"] for r in summary["eval_rows"] if not r["trained_on"])


def rescored_references(found: list[dict]) -> list[dict]:
    """References for runs scored on containers no reference counts as unseen.

    A run over a family scored on the catalogue has all 12 containers unseen, where the
    catalogue references count the red cup as trained on (the red-cup runs'). For such a
    run, each reference of its env evaluated on the same containers with as many episodes
    is given again with exactly the run's unseen containers unseen (named
    ``<reference>-unseen-<n>``): a reference row beside it and its aggregates.
    """
    refs = [s for s in found if s["algo"] in REFERENCES]
    have = {(s["env"], s["algo"], _unseen(s)) for s in refs}
    made: dict[str, dict] = {}
    for s in found:
        unseen = _unseen(s)
        if s["algo"] in REFERENCES or not unseen:
            continue
        for ref in refs:
            objects = {r["object"] for r in ref["eval_rows"]}
            if (
                ref["env"] != s["env"]
                or ref["eval_episodes"] != s["eval_episodes"]
                or (ref["env"], ref["algo"], unseen) in have
                or not unseen <= objects
            ):
                continue
            rows = [{**r, "trained_on": r["object"] not in unseen} for r in ref["eval_rows"]]
            name = f"{ref['run']}-unseen-{len(unseen)}"
            made[name] = {**ref, "run": name, "metrics": eval_metrics(rows), "eval_rows": rows}
    return list(made.values())


def unseen_returns(summaries: list[dict], objects: list[str]) -> np.ndarray:
    """``(runs, tasks)``: each run's mean return on each of ``objects`` (its unseen ones)."""
    table = []
    for s in summaries:
        by_object = {r["object"]: r["return"] for r in s["eval_rows"] if not r["trained_on"]}
        table.append([by_object[o] for o in objects])
    return np.asarray(table, dtype=np.float64)


def aggregates(group: list[dict], references: dict[str, dict]) -> dict | None:
    """Rliable's aggregates of a row over its seeds and unseen containers.

    Args:
        group: the row's run summaries (one per seed).
        references: this env's ``"scripted"`` and ``"random"`` reference summaries.

    Returns:
        ``{"iqm": (value, interval), "improvement": (value, interval), "tasks": n}`` (the
        intervals None for one seed), or
        None where a reference is missing or evaluated other containers, or where the
        row's runs were evaluated under reward weights of their own (their returns are in
        other units than the references').
    """
    if set(references) != {"scripted", "random"}:
        return None
    if any(k.endswith("_weight") for s in group for k in s.get("env_kwargs", {})):
        return None
    objects = sorted(r["object"] for r in group[0]["eval_rows"] if not r["trained_on"])
    try:
        scores = unseen_returns(group, objects)
        low = unseen_returns([references["random"]], objects)[0]
        high = unseen_returns([references["scripted"]], objects)
    except KeyError:  # the runs and the references saw different containers
        return None
    x = normalised(scores, low, high[0])
    expert = np.ones((1, len(objects)))
    # One seed: resampling seeds within each container has nothing to resample (the
    # interval would be the value twice), so none is given, as for the metrics.
    several = len(group) > 1
    return {
        "iqm": (float(iqm(x)), bootstrap_interval(iqm, x) if several else None),
        "improvement": (
            float(probability_of_improvement(x, expert)),
            bootstrap_interval(probability_of_improvement, x, expert) if several else None,
        ),
        "tasks": len(objects),
    }


def _algorithm(algo: str, kind: str) -> str:
    """A row's algorithm as the report names it."""
    # A clone (no update of the algorithm's own) is behaviour cloning, whatever network it
    # was cloned into (runs from before --algo bc record tqc).
    if kind == "clone":
        return "BC"
    name, _, exploration = algo.partition(" ")  # "ppo (gSDE)": PPO exploring by gSDE
    return " ".join([name.upper(), *([exploration] if exploration else [])])


def _aggregate_cell(value: tuple[float, tuple[float, float] | None] | None) -> str:
    if value is None:
        return "-"
    v, interval = value
    return f"{v:.2f}" + (f" [{interval[0]:.2f}, {interval[1]:.2f}]" if interval else "")


class RowKey(NamedTuple):
    """What makes runs seeds of one row.

    The env, how it learnt, which model, what it trained on and was scored on.
    """

    env: str
    algo: str
    recipe: str
    obs_mode: str
    kind: str
    model: str
    objects: str
    scored_on: str


def _group_key(s: dict) -> RowKey:
    """The row a run summary is a seed of."""
    algo = s["algo"] + (f" ({s['exploration']})" if s.get("exploration") else "")
    # A summary written before the report kept the recipe has none ("-", as a reference).
    return RowKey(
        s["env"], algo, s.get("recipe", "-"), s["obs_mode"], s["kind"],
        s.get("model", "last step"), s.get("objects") or "-", scored_on(s["eval_rows"]),
    )  # fmt: skip


def _cell(stat: dict, digits: int) -> str:
    """A metric's mean over seeds with its interval, as the report prints it."""
    if stat["mean"] is None:
        return "-"
    ci = stat["interval"]
    text = f"{stat['mean']:.{digits}f}"
    return text + (f" [{ci[0]:.{digits}f}, {ci[1]:.{digits}f}]" if ci else "")


def _minutes(wall: list[float], runs: int) -> str:
    """Mean wall minutes and their range; how many runs recorded it, if not all."""
    if not wall:
        return "-"
    text = (
        f"{wall[0]:.1f}"
        if len(wall) == 1
        else f"{np.mean(wall):.1f} ({min(wall):.1f}-{max(wall):.1f})"
    )
    return text + (f", {len(wall)} of {runs} runs" if len(wall) < runs else "")


def _plot(groups: dict[RowKey, list[dict]], path: Path) -> Path:
    """Learning curves, a panel per env.

    Each row's mean success against env steps, a band for its seeds' 95 % bootstrap
    interval.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    drawn: set[tuple] = set()
    panels: dict[str, list[tuple[str, list[int], np.ndarray]]] = {}
    for key, runs in sorted(groups.items()):
        curves = [r["curve"] for r in runs if r["curve"]]
        shapes = {(tuple(c["timesteps"]), tuple(c["success"])) for c in curves}
        if not curves or shapes <= drawn:
            continue  # the same runs' curves, another of their models evaluated
        drawn |= shapes
        steps = sorted(set.intersection(*(set(c["timesteps"]) for c in curves)))
        if not steps:
            continue
        ys = np.array(
            [[dict(zip(c["timesteps"], c["success"], strict=True))[x] for x in steps]
             for c in curves]
        )  # fmt: skip
        seeds = f"{len(curves)} seed" + ("s" if len(curves) > 1 else "")
        how = ", sampled" if "sampled" in key.model else ""
        recipe = f" {key.recipe}" if key.recipe != "-" else ""
        label = (
            f"{_algorithm(key.algo, key.kind)}{recipe} {key.obs_mode} on {key.objects}, "
            f"{key.kind}{how} ({seeds})"
        )
        panels.setdefault(key.env.split("/")[-1], []).append((label, steps, ys))
    names = sorted(panels) or ["-"]  # rows without curves (references) draw none
    fig, axes = plt.subplots(
        len(names), 1, figsize=(8, 2.6 * len(names) + 0.6), squeeze=False, sharex=True
    )
    for ax, name in zip(axes[:, 0], names, strict=True):
        for label, steps, ys in panels.get(name, []):
            line = ax.plot(steps, ys.mean(axis=0), "o-", label=label, markersize=3)[0]
            if len(ys) > 1:
                band = np.array([mean_interval(list(ys[:, k])) for k in range(len(steps))])
                ax.fill_between(steps, band[:, 0], band[:, 1], color=line.get_color(), alpha=0.2)
        # Log steps: a clone's 2000 steps and a learner's 400k on one axis.
        ax.set_xscale("log")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(name, fontsize=9, loc="left")
        ax.set_ylabel("success")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6.5, loc="upper left")
    axes[-1, 0].set_xlabel("environment steps")
    fig.suptitle(
        "Learning curves: success on the training containers as each row's model is scored;"
        "\nmean over seeds, band: its 95 % bootstrap interval",
        fontsize=9,
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def baselines_report(
    runs: list[str | Path] = (),
    reference: str | Path | list[str | Path] | None = None,
    summaries: Path = SUMMARIES,
    report: Path = REPORT,
    curves: Path = CURVES,
) -> dict:
    """Summarise runs into ``summaries``, then write the report and the curves from them all.

    Args:
        runs: ``train.py`` run directories (or folders of them) to add; may be empty to
            regenerate from the committed summaries.
        reference: evaluations of the scripted expert and of the random policy
            (``pour-gym evaluate scripted|random --json``), each added as a reference row
            (:func:`reference_summary`); both, per env and set of unseen containers, give
            the rows' aggregates.
        summaries: the folder of run summaries.
        report: the markdown report to write.
        curves: the learning curves' PNG.

    Returns:
        ``{"rows": [{env, algo, obs_mode, kind, model, objects, scored_on, seeds, each
        metric's mean and interval, timesteps, wall minutes, iqm and improvement (value,
        interval) or None}]}``.

    Raises:
        InputError: a folder that holds no finished run, or no summaries at all.
    """
    summaries = Path(summaries)
    summaries.mkdir(parents=True, exist_ok=True)
    for given in runs:
        given = Path(given)
        dirs = [given] if (given / "config.json").is_file() else sorted(
            p.parent for p in given.glob("*/eval.json")
        )  # fmt: skip
        if not dirs:
            raise InputError(f"{given} holds no finished train.py run (config.json, eval.json)")
        for d in dirs:
            for s in run_summaries(d):
                (summaries / f"{s['run']}.json").write_text(json.dumps(s, indent=1) + "\n")
    given_refs = [reference] if isinstance(reference, str | Path) else list(reference or [])
    for ref in given_refs:
        s = reference_summary(Path(ref))
        (summaries / f"{s['run']}.json").write_text(json.dumps(s, indent=1) + "\n")
    found = [json.loads(p.read_text()) for p in sorted(summaries.glob("*.json"))]
    if not found:
        raise InputError(f"no run summaries in {summaries}: pass --runs DIR")
    found += rescored_references(found)
    references: dict[tuple[str, str], dict[str, dict]] = {}
    for s in found:
        if s["algo"] in REFERENCES:
            references.setdefault((s["env"], scored_on(s["eval_rows"])), {})[s["algo"]] = s
    groups: dict[RowKey, list[dict]] = {}
    for s in found:
        groups.setdefault(_group_key(s), []).append(s)
    header = ["env", "algorithm", "recipe", "observation", "learnt from", "model", "trained on",
              "unseen", "seeds", *METRICS.values(), "normalised return, unseen (IQM)",
              "P(above the expert), unseen", "env steps", "wall time (min)"]  # fmt: skip
    table, rows = [], []
    for key, group in sorted(groups.items()):
        row = {**key._asdict(), "seeds": sorted(s["seed"] for s in group)}
        cells = []
        for name in METRICS:
            values = [s["metrics"][name] for s in group]
            present = [v for v in values if v is not None]
            row[name] = {"mean": float(np.mean(present)) if present else None,
                         "interval": mean_interval(present)}  # fmt: skip
            cells.append(_cell(row[name], 2 if "success" in name else 1))
        wall = [s["wall_seconds"] / 60 for s in group if s["wall_seconds"] is not None]
        steps = sorted({s["timesteps"] for s in group})
        agg = aggregates(group, references.get((key.env, key.scored_on), {}))
        row.update(
            timesteps=steps,
            wall_minutes=wall,
            iqm=agg and agg["iqm"],
            improvement=agg and agg["improvement"],
        )
        rows.append(row)
        table.append(
            [
                key.env.split("/")[-1],
                _algorithm(key.algo, key.kind),
                key.recipe,
                key.obs_mode,
                key.kind,
                key.model,
                key.objects,
                key.scored_on,
                str(len(group)),
                *cells,
                _aggregate_cell(row["iqm"]),
                _aggregate_cell(row["improvement"]),
                "/".join(f"{t:,}" for t in steps) if any(steps) else "-",
                _minutes(wall, len(group)),
            ]
        )
    _plot(groups, Path(curves))
    lines = [
        "# Baselines: algorithms x observations, over seeds",
        "",
        "<!-- Written by `pour-gym report baselines` from docs/baselines/runs/*.json. -->",
        "",
        "Each row is one way of training (on the red cup, or over a procedural family), run "
        "with several seeds; each cell is the mean over the seeds with a 95 % "
        "stratified-bootstrap interval over them in brackets (one seed: no interval). "
        "*Recipe*: the run's recipe in `agents/hyperparams.yaml` (`+ n --set`: with n of its "
        "arguments overridden; `-`: none, or a run summarised before the report kept it). "
        "*Trained on*: what the run trained on, and the success on its evaluation episodes "
        "of those containers; *unseen*: the containers the run never trained on that its "
        "unseen metrics are the mean over (the 11 catalogue containers but the red cup, all "
        "12 for a run over a family, or the members of `procedural:test`), each as source "
        "and target, at seeds training never used. Amount error is |poured - target| in "
        "particles (0.125 ml each). A *hand-written (reference)* row is the scripted "
        "expert on the same containers and seeds (it is not trained: its *trained on* "
        "success is the red cup's); a *uniform random (reference)* row, actions drawn "
        "uniformly from the action space, seeded per episode.",
        "",
        "The last two metrics follow rliable (Agarwal et al., 2021; "
        "`pour_gym.agents.evaluation.aggregate`), over the seeds x unseen containers: *normalised "
        "return* is each seed's mean return on a container as a share of the way from the "
        "random policy's (0) to the scripted expert's (1) on the same episodes (Minari's "
        "`ref_min_score` / `ref_max_score`), its interquartile mean (the mean of the middle "
        "half); *P(above the expert)* is the chance that a seed's return on a container "
        "beats the expert's (ties count a half), averaged over the containers; each with a "
        "95 % stratified-bootstrap interval (seeds resampled within each container; one seed: "
        "none). Above "
        "1 and above 0.5: beyond the expert. A row trained and evaluated with reward "
        "weights of its own (the residual's) has none: its returns are in other units.",
        "",
        markdown_table(header, table, align="llllllllr" + "r" * (len(METRICS) + 4)),
        "",
        f"![learning curves]({os.path.relpath(curves, Path(report).parent)})",
        "",
        "Runs: " + ", ".join(f"`{s['run']}`" for s in found) + ".",
        "",
    ]
    Path(report).write_text("\n".join(lines))
    return {"rows": rows}
