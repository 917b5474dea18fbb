"""Studies over a procedural family of containers, by shape: warping, and pouring policies.

:func:`family_warping`: the red cup's labels warped onto every member (as the
environments label it) against the member's labels from construction, IoU per part.

:func:`family_study`: every policy pours from each member into itself (source and target
the same container, ``episodes`` episodes each, seeds training never used), exactly as
:func:`~pour_gym.agents.evaluation.evaluate.evaluate_policy` evaluates any container. The members'
rows are then grouped by each shape parameter (:mod:`pour_gym.report.family`): success,
amount error and spill per profile, cross-section, lip, handle and binned height, rim
radius and wall, each success with a 95 % Wilson interval over the bucket's episodes.
Members the labelling or the environments refuse are counted and listed, not evaluated.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from pour_gym.agents.evaluation.aggregate import wilson_interval
from pour_gym.agents.evaluation.evaluate import evaluate_policy, failures_of, load_policy
from pour_gym.agents.evaluation.shapes import VALUES, member_buckets
from pour_gym.errors import InputError
from pour_gym.report.family import BINS, CATEGORIES, PARTS, bucket_tables, by_bucket, mean_of
from pour_gym.report.tables import markdown_table

# An evaluation row's pour profile: seconds the stream ran, its peak in target amounts per
# second (pour_gym.envs.task.pour_profile).
PROFILE = ("pour_seconds", "peak_flow")
# The study's table: a row per policy (and features, and liquid).
STUDY_HEADER = ["policy", "env", "features", "containers", "success", "amount error", "spilled",
                "failures"]  # fmt: skip

STUDY_SEED = 60_000  # the first evaluation seed (no training run uses 60000+)


def usable_members(family: str) -> tuple[list[str], list[dict]]:
    """The family's members the environments take, and those they refuse (with why)."""
    from pour_gym.assets import check_open, resolve_asset
    from pour_gym.objects.procedural import family_members

    usable, refused = [], []
    for name in family_members(family):
        try:
            check_open(resolve_asset(name), name)
        except InputError as exc:
            refused.append({"name": name, "reason": str(exc)})
            continue
        usable.append(name)
    return usable, refused


def perceivable_members(members: list[str], scan_seed: int = 0) -> tuple[list[str], list[dict]]:
    """The members the perception pipeline takes, and those it refuses (with why).

    Each is scanned, reconstructed and labelled once (10-30 s), then cached.
    """
    from tqdm import tqdm

    from pour_gym.assets import resolve_asset
    from pour_gym.perception import PerceptionError, perceived_asset

    taken, refused = [], []
    for name in tqdm(members, desc="perceive", file=sys.stderr):
        try:
            perceived_asset(resolve_asset(name), scan_seed)
        except PerceptionError as exc:
            refused.append({"name": name, "reason": exc.why})
            continue
        taken.append(name)
    return taken, refused


def family_study(
    family: str,
    policies: list[str],
    episodes: int = 2,
    seed: int = STUDY_SEED,
    perceptions: tuple[str, ...] = ("true",),
    scan_seed: int = 0,
    liquids: str | None = None,
    workers: int = 1,
) -> dict:
    """Evaluate each policy on every usable member of a family; group by shape.

    Args:
        family: a procedural family (``procedural:test``).
        policies: ``"scripted"``, shipped model names or model files
            (:func:`~pour_gym.agents.evaluation.evaluate.load_policy`).
        episodes: episodes per member.
        seed: the first episode's seed.
        perceptions: where the features' geometry comes from, one row per policy each:
            ``"true"`` (the labelled member) and ``"scan"`` (perceived: scanned,
            reconstructed and labelled by warping; :mod:`pour_gym.perception`).
        scan_seed: the scans' noise seed.
        liquids: comma-separated liquid presets (``"water,syrup,honey"``): each policy
            pours every member with each, the same episodes; None for the policy's own
            liquid (water unless its config says otherwise).
        workers: members evaluated at once, in threads (the same results for any number;
            :func:`~pour_gym.agents.evaluation.evaluate.evaluate_policy`).

    Returns:
        ``{"family", "episodes", "seed", "scan_seed", "liquids", "refused": [...],
        "refused_perception": [...], "policies": {label: {"policy", "perception",
        "liquid", "env", "mean": {success, success_interval, amount_error, spilled},
        "members": [rows with "spec"], "buckets": by_bucket(...)}}}``; a row with
        perceived features is labelled ``"<policy> (perceived)"``, a row with a liquid
        asked for ``"<policy> [<liquid>]"``.
    """
    from pour_gym.fluid.liquid import liquids_of
    from pour_gym.perception import PERCEPTIONS

    if episodes < 1:
        raise InputError(f"--episodes must be at least 1, not {episodes}")
    unknown = sorted(set(perceptions) - set(PERCEPTIONS))
    if unknown or not perceptions:
        raise InputError(f"--perception takes {', '.join(PERCEPTIONS)}, not {unknown or 'none'}")
    # Unknown names fail here, before any episode; None keeps each policy's own liquid.
    named = [x.name for x in liquids_of(liquids)] if liquids else [None]
    usable, refused = usable_members(family)
    if not usable:
        raise InputError(f"every member of {family} was refused: {refused[0]['reason']}")
    doc: dict = {"family": family, "episodes": episodes, "seed": seed, "scan_seed": scan_seed,
                 "liquids": named if liquids else [], "refused": refused,
                 "refused_perception": []}  # fmt: skip
    # Each loaded once, and before the scans: a bad name fails now, not after them.
    loaded_policies = {name: load_policy(name) for name in policies}
    members = {"true": usable}
    if "scan" in perceptions:
        members["scan"], doc["refused_perception"] = perceivable_members(usable, scan_seed)
    doc["policies"] = {}
    for name, perception, liquid in [(n, p, q) for n in policies for p in perceptions
                                      for q in named]:  # fmt: skip
        loaded = loaded_policies[name]
        kwargs = {**loaded.env_kwargs, "perception": perception, "scan_seed": scan_seed}
        if liquid is not None:
            kwargs["liquid"] = liquid
        result = evaluate_policy(
            loaded.policy, loaded.env_id, members[perception], episodes, seed=seed,
            env_kwargs=kwargs, trained_on=loaded.trained_on, workers=workers,
        )  # fmt: skip
        rows, buckets = member_buckets(result["rows"], episodes)
        n = len(rows) * episodes
        # The pour's profile too (how long the stream ran, its peak): what a liquid changes.
        keys = [*VALUES, *(k for k in PROFILE if all(k in r for r in rows))]
        mean = {key: float(np.mean([r[key] for r in rows])) for key in keys}
        mean["success_interval"] = wilson_interval(mean["success"] * n, n)
        label = name if perception == "true" else f"{name} (perceived)"
        if liquid is not None:
            label += f" [{liquid}]"
        doc["policies"][label] = {
            "policy": name, "perception": perception, "liquid": liquid, "env": loaded.env_id,
            "mean": mean, "members": rows, "buckets": buckets,
        }  # fmt: skip
    return doc


def plot_family_study(doc: dict, path: str | Path) -> Path:
    """Success (95 % Wilson intervals) per bucket of each shape parameter, one panel each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pour_gym.report.pictures import save_figure

    parameters = (*CATEGORIES, *BINS)
    names = list(doc["policies"])
    # A colour per policy and a marker per liquid: a study over liquids has a dozen rows.
    policies = list(dict.fromkeys(p["policy"] for p in doc["policies"].values()))
    liquids = doc.get("liquids") or [None]
    style = {
        name: {"color": f"C{policies.index(p['policy']) % 10}",
               "marker": "os^Dv"[liquids.index(p.get("liquid")) % 5] if p.get("liquid") else "o",
               "mfc": None if p.get("perception", "true") == "true" else "none"}
        for name, p in doc["policies"].items()
    }  # fmt: skip
    if len(names) == len(policies):  # one row per policy: the default cycle, as before
        style = {name: {"fmt": "o"} for name in names}
    legend_rows = -(-len(names) // 4)
    fig, axes = plt.subplots(
        1, len(parameters), figsize=(3.0 * len(parameters), 3.6 + 0.25 * legend_rows), sharey=True
    )
    for ax, parameter in zip(axes, parameters, strict=True):
        buckets = list(next(iter(doc["policies"].values()))["buckets"][parameter])
        for k, name in enumerate(names):
            groups = doc["policies"][name]["buckets"][parameter]
            # Side by side within a bucket's slot, however many rows (policies x liquids).
            x = np.arange(len(buckets)) + (k - (len(names) - 1) / 2) * min(0.15, 0.8 / len(names))
            # A bucket may be empty for a policy that saw fewer members (refused scans).
            shown = [i for i, b in enumerate(buckets) if b in groups]
            x = x[shown]
            y = np.array([groups[buckets[i]]["success"] for i in shown])
            lo_hi = np.array([groups[buckets[i]]["success_interval"] for i in shown])
            # Clipped at 0: a mean of per-container rates may differ from the interval's
            # count-based rate in its last bit.
            yerr = np.maximum([y - lo_hi[:, 0], lo_hi[:, 1] - y], 0.0)
            ax.errorbar(x, y, yerr=yerr, capsize=3, label=name, linestyle="none", **style[name])
        ax.set_xticks(np.arange(len(buckets)), buckets, rotation=45, ha="right", fontsize=8)
        ax.set_title(parameter.replace("_", " "))
        ax.set_ylim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success (95 % Wilson interval)")
    fig.suptitle(f"{doc['family']}: success by shape, {doc['episodes']} episodes per container")
    fig.tight_layout()
    # Below the panels, not over one: a panel of one policy's points hides under a dozen.
    handles, labels = axes[0].get_legend_handles_labels()
    fig.subplots_adjust(bottom=0.3 + 0.06 * legend_rows)
    fig.legend(handles, labels, loc="lower center", ncol=min(len(names), 4), fontsize=8)
    return save_figure(fig, path, dpi=90, tight=False)


def write_family_study(doc: dict, out: str | Path) -> Path:
    """Write ``summary.json``, ``success.png`` and ``report.md`` of a study into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(doc, indent=1) + "\n")
    plot_family_study(doc, out / "success.png")
    (out / "report.md").write_text(family_study_report(doc))
    return out


def family_study_report(doc: dict) -> str:
    """Markdown of :func:`family_study`: one row per policy, then each policy's buckets.

    A study over liquids has a row per policy and liquid, and tables with a column per
    liquid (:func:`liquids_pivot`).
    """
    rows = []
    for name, p in doc["policies"].items():
        m = p["mean"]
        # The failures by why, over the members' rows (studies from before outcomes: "-").
        # In the rows' own order (the env's outcomes'), so the cell reads the same each run.
        keys = dict.fromkeys(k for r in p["members"] for k in r if k.startswith("outcome_"))
        outcomes = mean_of(p["members"], tuple(keys))
        rows.append([f"`{name}`", p["env"], p.get("perception", "true"), str(len(p["members"])),
                     _success_cell(m), f"{m['amount_error']:.1f}",
                     f"{m['spilled']:.2f}", failures_of(outcomes)])  # fmt: skip
    asked = f" --liquids {','.join(doc['liquids'])}" if doc.get("liquids") else ""
    lines = [
        f"# Generalisation over {doc['family']}",
        "",
        f"Written by `pour-gym report generalisation --family {doc['family']}{asked}`: each "
        f"policy pours from every container it takes into itself, {doc['episodes']} episodes each "
        f"at seeds {doc['seed']}+ (never used in training). Success is the share of episodes "
        "that ended with the target amount within tolerance, nothing spilled and the source "
        "upright; brackets hold a 95 % Wilson interval over the episodes. Amount error is "
        "|poured - target| in particles. Features: `true`, from each member's labelled "
        "mesh; `scan`, perceived as a robot would (each member scanned on the simulated "
        f"turntable with noise seed {doc.get('scan_seed', 0)}, reconstructed and labelled "
        "by warping the red cup; the physics keeps the true mesh).",
        "",
        markdown_table(
            STUDY_HEADER,
            rows,
            align="lllrrrrl",
        ),
    ]
    if doc.get("liquids"):
        lines += ["", "By liquid (each cell: success [95 % interval]; amount error; spilled, "
                  "in particles per episode):", "", liquids_pivot(doc)]  # fmt: skip
    lines += ["", "![success by shape](success.png)"]
    refused = doc["refused"]
    lines += ["", f"Refused by the labelling or the environments: {len(refused)}."]
    lines += [f"- `{r['name']}`: {r['reason']}" for r in refused]
    if any(p.get("perception") == "scan" for p in doc["policies"].values()):
        seen = doc.get("refused_perception", [])
        lines += ["", f"Refused by the perception pipeline (scan, reconstruction, warping): "
                  f"{len(seen)}."]  # fmt: skip
        lines += [f"- `{r['name']}`: {r['reason']}" for r in seen]
    for name, p in doc["policies"].items():
        lines += ["", f"## `{name}` by shape", "", bucket_tables(p["buckets"], VALUES)]
    return "\n".join(lines) + "\n"


def _success_cell(mean: dict) -> str:
    """``0.95 [0.92, 0.98]``: a success rate with its 95 % Wilson interval."""
    lo, hi = mean["success_interval"]
    return f"{mean['success']:.2f} [{lo:.2f}, {hi:.2f}]"


def liquids_pivot(doc: dict) -> str:
    """Markdown of a study over liquids: a row per policy (and features), a column per liquid.

    Each cell is the success over the family with its 95 % Wilson interval, then the mean
    amount error and spill in particles, so that one liquid's cost to a policy reads along
    its row; a second table gives the pours' duration and peak flow the same way.
    """
    liquids = doc["liquids"]
    cells: dict[tuple[str, str], dict[str, dict]] = {}
    for p in doc["policies"].values():
        key = (p["policy"], p.get("perception", "true"))
        cells.setdefault(key, {})[p["liquid"]] = p["mean"]

    def table(what: str, cell, needs: tuple[str, ...]) -> str:
        rows = [
            [f"`{policy}`", perception]
            + [cell(by_liquid[q]) if all(k in by_liquid.get(q, {}) for k in needs) else "-"
               for q in liquids]
            for (policy, perception), by_liquid in cells.items()
        ]  # fmt: skip
        header = ["policy", "features", *(f"{q}: {what}" for q in liquids)]
        return markdown_table(header, rows, align="ll" + "r" * len(liquids))

    scores = table(
        "success; error; spilled",
        lambda m: f"{_success_cell(m)}; {m['amount_error']:.1f}; {m['spilled']:.2f}",
        VALUES,
    )
    pours = table(
        "pour, s; peak flow, T/s",
        lambda m: f"{m['pour_seconds']:.2f}; {m['peak_flow']:.2f}",
        PROFILE,
    )
    return (
        f"{scores}\n\nThe pours (mean over the episodes: how long the stream ran, and its "
        f"peak in target amounts per second):\n\n{pours}"
    )


def family_warping(family: str) -> dict:
    """Warp the red cup's labels onto every member of a family; IoU against construction.

    The labelling is the environments' own (:func:`pour_gym.assets.resolve_asset`: the
    ``best`` method from the red cup, cached), so the members labelled here are the ones
    the environments then load. A member the labelling refuses (an InputError: it found
    no opening, no cavity) is counted and listed with the reason, not averaged.

    Args:
        family: a procedural family name (``procedural:test``).

    Returns:
        ``{"family", "method", "source", "members": [{"name", "spec", "iou_<part>"...,
        "lip_depth" (m, None where the warp's rim band was kept), "lip_reason"}],
        "refused": [{"name", "reason"}], "mean": {"iou_<part>": mean}, "buckets":
        by_bucket(...)}``.
    """
    from tqdm import tqdm

    from pour_gym.assets import resolve_asset
    from pour_gym.objects.procedural import family_members, member_spec

    names = family_members(family)
    members, refused = [], []
    method, source = "best", "red_cup"
    for name in tqdm(names, desc=f"label {family}", file=sys.stderr):
        try:
            meta = resolve_asset(name).meta
            method, source = meta["source"]["method"], meta["source"]["object"]
        except InputError as exc:
            refused.append({"name": name, "reason": str(exc)})
            continue
        row = {"name": name, "spec": member_spec(name).to_dict()}
        row.update({f"iou_{part}": meta["iou"][part] for part in PARTS})
        lip = meta["source"].get("transfer", {}).get("lip", {})
        row["lip_depth"], row["lip_reason"] = lip.get("depth"), lip.get("reason", "")
        members.append(row)
    values = tuple(f"iou_{part}" for part in PARTS)
    return {
        "family": family,
        "method": method,
        "source": source,
        "members": members,
        "refused": refused,
        "mean": mean_of(members, values),
        "buckets": by_bucket(members, values),
    }


def family_warping_report(doc: dict) -> str:
    """Markdown of :func:`family_warping`: the means, the refusals, then every bucket."""
    values = tuple(f"iou_{part}" for part in PARTS)
    m = doc["mean"]
    means = ", ".join(f"{v} {m[v]:.3f}" for v in values if m[v] is not None)
    lines = [
        f"# Warping over {doc['family']}",
        "",
        f"Written by `pour-gym report warping --family {doc['family']}`: the {doc['source']}'s "
        f"labels warped ({doc['method']}) onto each of {len(doc['members']) + len(doc['refused'])} "
        "procedural containers, against each one's labels from construction (IoU per part, "
        "vertex by vertex; the handle's only where there is one).",
        "",
        f"Mean over {m['members']} members: {means}.",
    ]
    kept = [r for r in doc["members"] if r.get("lip_depth") is None]
    lines += ["", f"The rim fitted to the lip (`pour_gym.warp.lip`) on "
              f"{len(doc['members']) - len(kept)} of {len(doc['members'])} members; the "
              f"warp's band kept on {len(kept)}" + (":" if kept else ".")]  # fmt: skip
    lines += [f"- `{r['name']}`: {r['lip_reason']}" for r in kept]
    if doc["refused"]:
        lines += ["", f"Refused ({len(doc['refused'])}):", ""]
        lines += [f"- `{r['name']}`: {r['reason']}" for r in doc["refused"]]
    else:
        lines += ["", "Refused: none."]
    lines += ["", bucket_tables(doc["buckets"], values)]
    return "\n".join(lines) + "\n"
