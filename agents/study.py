"""The generalisation study: warped features against raw state on unseen containers.

The same agent is trained on the red cup with the warped features or with raw state and
evaluated on containers it never saw.

:func:`study_report` gathers the runs of ``docs/generalisation/run.sh`` (``train.py``
run directories, each with ``config.json`` and ``eval.json``) into one markdown report
with a table and a bar chart per environment.
"""

from __future__ import annotations

import json
from pathlib import Path

from pour_gym.errors import InputError


def _load_runs(root: Path) -> dict[str, dict[str, dict]]:
    runs: dict[str, dict[str, dict]] = {}
    for eval_path in sorted(root.glob("*/eval.json")):
        config = json.loads((eval_path.parent / "config.json").read_text())
        runs.setdefault(config["env"], {})[config["obs_mode"]] = {
            "config": config,
            "eval": json.loads(eval_path.read_text()),
        }
    if not runs:
        raise InputError(f"no runs under {root} (run docs/generalisation/run.sh first)")
    return runs


def _plot(env: str, modes: dict[str, dict], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    names = [r["object"] for r in next(iter(modes.values()))["eval"]["rows"]]
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.8 / len(modes)
    for k, (mode, run) in enumerate(sorted(modes.items())):
        values = [r["success"] for r in run["eval"]["rows"]]
        ax.bar(x + (k - (len(modes) - 1) / 2) * width, values, width, label=f"obs_mode={mode}")
    ax.set_xticks(x, [n + (" *" if n == "red_cup" else "") for n in names], rotation=35,
                  ha="right", fontsize=8)  # fmt: skip
    ax.set_ylabel("success rate (correct decisions)")
    ax.set_ylim(0, 1.05)
    ax.set_title(f"{env}: trained on red_cup (*), evaluated on every container")
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def study_report(runs_dir: str | Path, out: str | Path) -> dict:
    """Write ``report.md`` and one PNG per environment; returns the numbers.

    Returns:
        ``{env: {mode: {"trained": success on red_cup, "unseen": mean success on the
        others, "rows": [...]}}}``.
    """
    root, out = Path(runs_dir), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs = _load_runs(root)
    summary: dict = {}
    lines = [
        "# Generalisation: warped features against raw state",
        "",
        "PPO agents trained on the red cup alone (the thesis's training set), once with the",
        "warped high-level features as observations and once with raw state (positions and",
        "bounding-box sizes, no labels), then evaluated on the nine thesis objects and the",
        "pybullet mug. Numbers are the fraction of correct decisions over the evaluation",
        "episodes per container (seeds fixed in `train.py`'s evaluation).",
        "",
        "Reproduce (about 20 minutes on a 2-core machine):",
        "",
        "```",
        "sh docs/generalisation/run.sh",
        "```",
        "",
    ]
    for env, modes in sorted(runs.items()):
        summary[env] = {}
        cfg = next(iter(modes.values()))["config"]
        lines += [
            f"## {env}",
            "",
            f"{cfg['algo'].upper()}, {cfg['timesteps']} steps, seed {cfg['seed']}, "
            f"{next(iter(modes.values()))['eval']['episodes']} evaluation episodes per "
            "container.",
            "",
        ]
        ordered = sorted(modes)
        lines.append("| container | " + " | ".join(ordered) + " |")
        lines.append("|---|" + "---:|" * len(ordered))
        rows = {m: {r["object"]: r for r in modes[m]["eval"]["rows"]} for m in ordered}
        names = list(rows[ordered[0]])
        for name in names:
            cells = [f"{rows[m][name]['success']:.2f}" for m in ordered]
            lines.append(f"| {name}{' (trained)' if name == 'red_cup' else ''} | "
                         + " | ".join(cells) + " |")  # fmt: skip
        for m in ordered:
            unseen = [r["success"] for n, r in rows[m].items() if not r["trained_on"]]
            trained = [r["success"] for r in rows[m].values() if r["trained_on"]]
            summary[env][m] = {
                "trained": sum(trained) / max(len(trained), 1),
                "unseen": sum(unseen) / max(len(unseen), 1),
            }
        lines.append(
            "| mean over unseen | "
            + " | ".join(f"{summary[env][m]['unseen']:.2f}" for m in ordered)
            + " |"
        )
        png = _plot(env, modes, out / f"{env.split('/')[-1]}.png")
        lines += ["", f"![{env}]({png.name})", ""]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary
