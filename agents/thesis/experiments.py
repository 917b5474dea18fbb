"""The thesis's two experiments (5.2), with ROC curves per object.

Experiment 1 (``drop``, ParticleDrop-v0): will fluid released here end up in the
container? Features f1, f2, f3. Experiment 2 (``tilt``, TiltPour-v0): will the container
pour when tilted to this angle? Feature f4. The classifier is the thesis's logistic
regression fitted by Newton-Raphson (``pour_gym.warp.classifiers.LogisticRegression``),
trained on the red cup alone and applied to each object and to all at once. The thesis's
criterion is the true-positive rate at a false-positive rate of at most 1 % (pouring
where fluid would spill must not happen).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pour_gym.agents.cluster import map_tasks, ray_session
from pour_gym.agents.policies.rollout import rollout
from pour_gym.assets import SPLITS
from pour_gym.envs import PARTICLE_DROP_V0, TILT_POUR_V0, make
from pour_gym.errors import InputError
from pour_gym.report.tables import markdown_table
from pour_gym.warp.classifiers import LogisticRegression

EXPERIMENTS = {
    "drop": (PARTICLE_DROP_V0, ("f1", "f2", "f3")),
    "tilt": (TILT_POUR_V0, ("f4",)),
}
TRAIN_OBJECT = "red_cup"
MAX_FPR = 0.01
# Episodes per task: small enough for a progress bar that moves and for the tasks to spread
# over workers, large enough that making the env is a small part of a task.
CHUNK = 20


@dataclass
class Dataset:
    """Features and labels of one experiment.

    Attributes:
        features: (N, M) features per episode.
        labels: (N,) bool ground truth.
        objects: (N,) container of each episode.
    """

    features: np.ndarray
    labels: np.ndarray
    objects: np.ndarray

    def save(self, path: str | Path) -> Path:
        """Write as ``.npz``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(
            path, features=self.features, labels=self.labels, objects=self.objects.astype(str)
        )
        return path


def collect_chunk(task: dict) -> tuple[list, list]:
    """Episodes of one container in an env of their own: features and labels.

    A function of plain data, so that it runs the same here or as a Ray task.

    Args:
        task: ``env_id``, ``object`` (a container) and ``seeds`` (one episode each).
    """
    env = make(task["env_id"], objects=[task["object"]])

    def abstain(_obs: np.ndarray) -> np.ndarray:
        # The action does not change what happens, only the reward: the data is the label.
        return np.zeros(1, dtype=np.float32)

    try:
        infos = [rollout(env, abstain, seed=s).info for s in task["seeds"]]
    finally:
        env.close()
    return [i["features"] for i in infos], [i["label"] for i in infos]


def collect(
    experiment: str,
    objects: tuple[str, ...],
    episodes: int,
    seed: int = 0,
    address: str | None = None,
    chunk: int = CHUNK,
) -> Dataset:
    """Run the experiment's environment ``episodes`` times per object.

    Args:
        experiment: ``"drop"`` or ``"tilt"``.
        objects: containers (catalogue names or mesh paths).
        episodes: episodes per object.
        seed: seed of the first episode (each episode has its own).
        address: run chunks of episodes as Ray tasks there (``local``, ``auto`` or
            ``HOST:PORT``, see :mod:`pour_gym.agents.cluster`); None: here, one after another.
            The dataset is the same either way.
        chunk: episodes per task.

    Returns:
        The dataset, in the order of the objects.
    """
    env_id, _ = _spec(experiment)
    tasks = [
        {
            "env_id": env_id,
            "object": name,
            "seeds": [seed + k * episodes + ep for ep in range(lo, min(lo + chunk, episodes))],
        }
        for k, name in enumerate(objects)
        for lo in range(0, episodes, chunk)
    ]
    desc = f"experiment {experiment} ({chunk} episodes a task)"
    with ray_session(address) as ray:
        parts = map_tasks(collect_chunk, tasks, ray, desc=desc)
    feats = [f for part, _ in parts for f in part]
    labels = [y for _, part in parts for y in part]
    names = [t["object"] for t in tasks for _ in t["seeds"]]
    return Dataset(np.asarray(feats, dtype=float), np.asarray(labels, bool), np.asarray(names))


def roc_curve(scores: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """False- and true-positive rates over all thresholds (descending scores).

    Returns:
        ``(fpr, tpr)``, each starting at 0 and ending at 1; ties share one point.
    """
    scores, labels = np.asarray(scores, float), np.asarray(labels, bool)
    pos, neg = int(labels.sum()), int((~labels).sum())
    if pos == 0 or neg == 0:
        raise InputError("a ROC curve needs both positive and negative examples")
    order = np.argsort(-scores, kind="stable")
    s, y = scores[order], labels[order]
    tp, fp = np.cumsum(y), np.cumsum(~y)
    last = np.r_[np.nonzero(np.diff(s))[0], len(s) - 1]  # last index of each tie group
    return np.r_[0.0, fp[last] / neg], np.r_[0.0, tp[last] / pos]


def auc(fpr: np.ndarray, tpr: np.ndarray) -> float:
    """Area under a ROC curve (trapezoids)."""
    return float(np.trapezoid(tpr, fpr))


def tpr_at_fpr(fpr: np.ndarray, tpr: np.ndarray, max_fpr: float = MAX_FPR) -> float:
    """The best true-positive rate among thresholds with a false-positive rate <= max_fpr."""
    ok = fpr <= max_fpr + 1e-12
    return float(tpr[ok].max())


def _spec(experiment: str) -> tuple[str, tuple[str, ...]]:
    if experiment not in EXPERIMENTS:
        raise InputError(f"unknown experiment {experiment!r}; use {' or '.join(EXPERIMENTS)}")
    return EXPERIMENTS[experiment]


def evaluate(data: Dataset, train_object: str = TRAIN_OBJECT) -> dict:
    """Train on one object's episodes, score every object's and all of them together.

    Returns:
        ``{"auc": {obj: x, "all": x}, "tpr_at_fpr_0.01": {...}, "positives": {...},
        "episodes": {...}, "classifier": {...}, "curves": {obj: (fpr, tpr)}}``.
    """
    train = data.objects == train_object
    if not train.any():
        raise InputError(f"no episodes of {train_object!r} to train on")
    clf = LogisticRegression().fit(data.features[train], data.labels[train])
    scores = clf.predict_proba(data.features)
    out: dict = {"auc": {}, "tpr_at_fpr_0.01": {}, "positives": {}, "episodes": {}, "curves": {}}
    groups = [(o, data.objects == o) for o in dict.fromkeys(data.objects.tolist())]
    for name, mask in [*groups, ("all", np.ones(len(data.labels), bool))]:
        fpr, tpr = roc_curve(scores[mask], data.labels[mask])
        out["auc"][name] = auc(fpr, tpr)
        out["tpr_at_fpr_0.01"][name] = tpr_at_fpr(fpr, tpr)
        out["positives"][name] = float(data.labels[mask].mean())
        out["episodes"][name] = int(mask.sum())
        out["curves"][name] = (fpr, tpr)
    out["classifier"] = clf.to_dict()
    return out


def plot_roc(result: dict, title: str, path: str | Path) -> Path:
    """ROC curves of every object in one picture (like the thesis's figures 5.8, 5.10)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pour_gym.report.pictures import save_figure

    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    for name, (fpr, tpr) in result["curves"].items():
        style = {"color": "black", "lw": 2.5} if name == "all" else {"lw": 1.2}
        ax.step(fpr, tpr, where="post", label=f"{name} (AUC {result['auc'][name]:.3f})", **style)
    ax.axvline(MAX_FPR, color="grey", ls=":", lw=1)
    ax.set_xlabel("false-positive rate")
    ax.set_ylabel("true-positive rate")
    ax.set_title(title)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.01)
    ax.legend(fontsize=7, loc="lower right")
    return save_figure(fig, path)


def results_table(result: dict) -> str:
    """AUC and TPR at FPR <= 1 % per object."""
    rows = [
        [name, result["episodes"][name], f"{result['positives'][name]:.2f}",
         f"{result['auc'][name]:.3f}", f"{result['tpr_at_fpr_0.01'][name]:.3f}"]
        for name in result["auc"]
    ]  # fmt: skip
    return markdown_table(["object", "episodes", "positives", "AUC", "TPR at FPR <= 1 %"], rows)


def run_experiment(
    experiment: str,
    episodes: int = 400,
    seed: int = 0,
    out: str | Path = "experiments",
    objects: tuple[str, ...] | None = None,
    address: str | None = None,
) -> dict:
    """Collect, train on the red cup, evaluate, and write dataset, PNG, JSON and table.

    Args:
        experiment: ``"drop"`` or ``"tilt"``.
        episodes: episodes per object.
        seed: first seed.
        out: output folder.
        objects: containers (default: the thesis's nine objects).
        address: collect on Ray there (see :func:`collect`).

    Returns:
        The JSON document (``auc``, ``tpr_at_fpr_0.01``, ...) and the written paths.
    """
    _, names = _spec(experiment)
    if episodes < 10:
        raise InputError(f"--episodes must be at least 10 per object, not {episodes}")
    objects = objects or SPLITS["all"]
    data = collect(experiment, objects, episodes, seed, address=address)
    result = evaluate(data)
    out = Path(out)
    title = {
        "drop": "Experiment 1: will the fluid increase the volume? (f1, f2, f3)",
        "tilt": "Experiment 2: will the container start to pour? (f4)",
    }[experiment]
    png = plot_roc(result, title, out / f"roc_{experiment}.png")
    dataset = data.save(out / f"dataset_{experiment}.npz")
    doc = {
        "experiment": experiment,
        "features": list(names),
        "train_object": TRAIN_OBJECT,
        "episodes_per_object": episodes,
        "seed": seed,
        "auc": result["auc"],
        "tpr_at_fpr_0.01": result["tpr_at_fpr_0.01"],
        "positives": result["positives"],
        "classifier": result["classifier"],
        "files": {"png": str(png), "dataset": str(dataset)},
    }
    (out / f"results_{experiment}.json").write_text(json.dumps(doc, indent=2) + "\n")
    table = results_table(result)
    objects_flag = (
        "" if tuple(objects) == tuple(SPLITS["all"]) else f" --objects {','.join(objects)}"
    )
    command = f"pour-gym experiment {experiment} --episodes {episodes} --seed {seed}{objects_flag}"
    page = (
        f"# {title}\n\nWritten by `{command} --out {out}`: the logistic regression trained on "
        f"the {TRAIN_OBJECT} alone, evaluated on every object.\n\n{table}\n\n"
        f"![ROC curves]({png.name})\n"
    )
    (out / f"results_{experiment}.md").write_text(page)
    doc["table"] = table
    return doc
