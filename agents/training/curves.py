"""Learning curves and the callbacks of a training run.

A curve point is the policy's episodes on the training containers (its mean action, or its
seeded samples with ``--stochastic-eval``), scored by
the env's task (:meth:`pour_gym.envs.task.Task.metrics`: success, return, and for a
pouring task the amount error and the spill), appended to ``curve.csv`` (against
environment steps) or ``bc_curve.csv`` (against behaviour-cloning gradient steps);
``curve.png`` draws both.
"""

from __future__ import annotations

import csv
import json
import shutil
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pour_gym.agents.policies.rollout import rollout, sb3_policy
from pour_gym.agents.training.config import TrainConfig
from pour_gym.agents.training.moved_modules import importable_old_paths
from pour_gym.agents.training.runs import (
    BEST,
    NORMALISER,
    Run,
    checkpoint_file,
    keep_if_best,
    rank_point,
    save_normaliser,
)
from pour_gym.envs import Task, make, mean_metrics, task_of
from pour_gym.errors import InputError

# The curve's episodes start from seeds this far beyond the evaluation's first.
CURVE_SEED_OFFSET = 500_000


def record_curve_point(
    config: TrainConfig,
    out: Path,
    model,
    venv,
    env_kwargs: dict,
    name: str = "curve.csv",
    x: tuple[str, int] | None = None,
) -> dict:
    """Evaluate the current policy on the training containers; append to ``name``.

    Args:
        config: the run's config (env, episodes and seeds of a point).
        out: the run directory.
        model: the SB3 algorithm.
        venv: the training's vector env (its normaliser, if it is one, is used).
        env_kwargs: the training env's arguments.
        name: the CSV file.
        x: the point's abscissa (name, value): the model's environment steps by default,
            ``("bc_steps", k)`` for the behaviour-cloning curve (``bc_curve.csv``).

    Returns:
        The point: the abscissa and the task's metrics, each a mean over the episodes.
    """
    from stable_baselines3.common.vec_env import VecNormalize

    normaliser = venv if isinstance(venv, VecNormalize) else None
    # The run's config.json (written when the run starts) says how its model acts (a
    # residual on the expert, say).
    saved = out / "config.json"
    run_config = json.loads(saved.read_text()) if saved.is_file() else {}
    run = Run(model=model, config=run_config, normaliser=normaliser)
    policy = sb3_policy(run, deterministic=not config.stochastic_eval)
    task = task_of(config.env)
    env = make(config.env, **env_kwargs)
    seed = config.eval_seed + CURVE_SEED_OFFSET
    episodes = [rollout(env, policy, seed=seed + k) for k in range(config.curve_episodes)]
    env.close()
    key, value = x if x is not None else ("timesteps", int(model.num_timesteps))
    point = {
        key: int(value),
        **mean_metrics(e.metrics(task) for e in episodes),
        **task.outcome_shares(e.info for e in episodes),
    }
    path = out / name
    new = not path.is_file()
    with open(path, "a") as fh:
        if new:
            fh.write(",".join(point) + "\n")
        fh.write(",".join(f"{v:g}" for v in point.values()) + "\n")
    return point


def record_curve_from_checkpoints(config: TrainConfig, out: Path, env_kwargs: dict) -> list[dict]:
    """Measure a run's learning curve again from its checkpoints; ``curve.csv`` rewritten.

    At every ``curve_every`` steps up to ``timesteps``, the checkpoint's policy (with the
    normaliser saved beside it) plays ``curve_episodes`` episodes from the curve's seeds.
    That is the curve the run would have recorded with these settings: a curve point's
    episodes run in an env of their own, with the policy's mean action (or, with
    ``--stochastic-eval``, its samples from seeds of their own), and change nothing in the
    training. More episodes a point make ``--keep-best``'s choice less a matter of luck;
    ``--stochastic-eval`` draws the curve of the policy the evaluation will score. The
    evaluation's seeds stay unseen.

    Args:
        config: the run's config (env, curve steps and episodes, seeds, algorithm).
        out: the run directory.
        env_kwargs: the training env's arguments.

    Returns:
        The points.

    Raises:
        InputError: a curve step without its checkpoint (or, when the run normalises, the
            statistics beside it).
    """
    import pickle

    from pour_gym.agents.training.config import algorithm

    if config.curve_every <= 0:
        raise InputError("--recurve measures learning-curve points: add --curve-every N")
    folder = out / "checkpoints"
    steps = range(config.curve_every, config.timesteps + 1, config.curve_every)
    loaded = []
    for step in steps:
        model = checkpoint_file(folder, step)
        stats = checkpoint_file(folder, step, "normaliser")
        if not model.is_file() or ((out / NORMALISER).is_file() and not stats.is_file()):
            raise InputError(
                f"{out}: no checkpoint of {step} steps ({model.name} with its statistics) to "
                "measure the curve at; --curve-every must be a multiple of --checkpoint-every"
            )
        loaded.append((step, model, stats if stats.is_file() else None))
    (out / "curve.csv").unlink(missing_ok=True)
    points = []
    cls = algorithm(config.algo)
    for step, model, stats in tqdm(loaded, desc="curve", file=sys.stderr):
        normaliser = None
        if stats is not None:
            with open(stats, "rb") as fh:
                normaliser = pickle.load(fh)  # a VecNormalize without its env
        importable_old_paths()  # a checkpoint saved before the agents were grouped
        agent = cls.load(model, device="cpu")
        points.append(
            record_curve_point(config, out, agent, normaliser, env_kwargs, x=("timesteps", step))
        )
    return points


def read_curve(path: Path) -> dict[str, np.ndarray] | None:
    """A learning curve's CSV as columns (None if missing or empty)."""
    if not path.is_file():
        return None
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return None
    return {
        key: np.array([float(r[key]) if r[key] not in ("", "None") else np.nan for r in rows])
        for key in rows[0]
    }


def keep_best_of_curve(out: Path, task: Task) -> dict | None:
    """Make ``best/`` hold the model of the best point of the run's whole learning curve.

    During training :func:`~pour_gym.agents.training.runs.keep_if_best` keeps each new
    best point's model as the point is recorded. A run resumed without ``best/``, or
    trained without ``--keep-best`` and asked for it afterwards, has points whose models
    are only in ``checkpoints/`` (a checkpoint falls on every curve point when
    ``--checkpoint-every`` divides ``--curve-every``): this takes the point
    :func:`keep_if_best` would have kept (the first of the highest rank) from there.

    Args:
        out: the run directory.
        task: the env's task (what ranks second after success).

    Returns:
        The best point, or None for a run without a learning curve.

    Raises:
        InputError: the best point's model (or, for a normalising run, its statistics) is
            neither in ``best/`` nor in a checkpoint.
    """
    curve = read_curve(out / "curve.csv")
    if curve is None:
        return None
    points = [{k: float(v[i]) for k, v in curve.items()} for i in range(len(curve["timesteps"]))]
    ranks = [rank_point(p, task) for p in points]
    point = points[ranks.index(max(ranks))]  # the first of equals, as keep_if_best keeps
    steps = point["timesteps"] = int(point["timesteps"])
    folder = out / BEST
    kept = folder / "point.json"
    if kept.is_file() and json.loads(kept.read_text()).get("timesteps") == steps:
        kept.write_text(json.dumps(point) + "\n")  # the model kept; the curve may be new
        return point
    model = checkpoint_file(out / "checkpoints", steps)
    if not model.is_file():
        raise InputError(
            f"{out}: the best learning-curve point ({steps} steps) has no checkpoint "
            f"({model.name}); --keep-best needs --checkpoint-every to divide --curve-every"
        )
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(model, folder / "model.zip")
    stats = checkpoint_file(out / "checkpoints", steps, "normaliser")
    if (out / NORMALISER).is_file():  # the run normalises: the point's statistics too
        if not stats.is_file():
            raise InputError(f"{out}: the checkpoint of {steps} steps has no {stats.name}")
        shutil.copyfile(stats, folder / NORMALISER)
    kept.write_text(json.dumps(point) + "\n")
    return point


def plot_curve(out: Path, title: str) -> Path | None:
    """``curve.png``: success and return against behaviour-cloning and environment steps.

    One row per curve the run has: ``bc_curve.csv`` (during behaviour cloning on the
    demonstrations, against gradient steps) and ``curve.csv`` (during training, against
    environment steps). For a pouring task, a second panel shows the amount error and
    the spill.
    """
    curves = [
        (data, key, label)
        for name, key, label in (
            ("bc_curve.csv", "bc_steps", "behaviour-cloning gradient steps"),
            ("curve.csv", "timesteps", "environment steps"),
        )
        if (data := read_curve(out / name)) is not None
    ]
    if not curves:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pour = any(
        "amount_error" in d and not np.all(np.isnan(d["amount_error"])) for d, _, _ in curves
    )
    outcomes = pour and any("outcome_success" in d for d, _, _ in curves)
    ncols = 1 + int(pour) + int(outcomes)
    fig, axes = plt.subplots(
        len(curves), ncols, figsize=(4 + 3.5 * ncols, 4 * len(curves)), squeeze=False
    )
    for row, (data, key, label) in enumerate(curves):
        ax = axes[row, 0]
        steps = data[key]
        ax.plot(steps, data["success"], "o-", label="success rate")
        ax.set_xlabel(label)
        ax.set_ylabel("success rate (as the run scores its policy)")
        ax.set_ylim(-0.02, 1.02)
        ax2 = ax.twinx()
        ax2.plot(steps, data["return"], "s--", color="tab:orange", label="return")
        ax2.set_ylabel("mean return")
        ax.legend(loc="upper left", fontsize=8)
        ax2.legend(loc="lower right", fontsize=8)
        if pour:
            ax = axes[row, 1]
            ax.plot(steps, data["amount_error"], "o-", color="tab:red", label="|poured - target|")
            ax.plot(steps, data["spilled"], "s--", color="tab:purple", label="spilled")
            ax.set_xlabel(label)
            ax.set_ylabel("particles (mean per episode)")
            ax.legend(fontsize=8)
        if outcomes and "outcome_success" in data:
            # Why episodes end as they do, stacked: a curve of what the learner gets wrong.
            names = [k for k in data if k.startswith("outcome_")]
            ax = axes[row, 2]
            ax.stackplot(steps, [data[k] for k in names],
                         labels=[k.removeprefix("outcome_") for k in names])  # fmt: skip
            ax.set_xlabel(label)
            ax.set_ylabel("share of episodes")
            ax.set_ylim(0, 1)
            ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    png = out / "curve.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def training_callbacks(
    config: TrainConfig, out: Path, total: int, done: int, n_envs: int, env_kwargs: dict
):
    """Checkpoints (with the normaliser), a progress bar and the learning curve.

    Args:
        config: the run's config.
        out: the run directory.
        total: the steps the run ends at.
        done: the steps already taken (a resumed run's).
        n_envs: environments stepped side by side.
        env_kwargs: the training env's arguments (for the curve's episodes).
    """
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback

    task = task_of(config.env)

    class Bar(BaseCallback):
        def _on_training_start(self) -> None:
            self.bar = tqdm(total=total, initial=done, desc="train", file=sys.stderr)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    class Curve(BaseCallback):
        """Success and return of the policy (as the run scores it) on the training containers."""

        def __init__(self):
            super().__init__()
            self.next = (done // config.curve_every + 1) * config.curve_every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self.next += config.curve_every
                point = record_curve_point(config, out, self.model, self.training_env, env_kwargs)
                if config.keep_best:
                    keep_if_best(out / BEST, point, self.model, self.training_env, task)
            return True

    class SaveNormaliser(BaseCallback):
        def _on_step(self) -> bool:
            if self.n_calls % max(config.checkpoint_every // n_envs, 1) == 0:
                save_normaliser(self.training_env, out / "checkpoints", self.num_timesteps)
            return True

    callbacks = [
        CheckpointCallback(
            max(config.checkpoint_every // n_envs, 1),
            str(out / "checkpoints"),
            name_prefix="model",
            save_replay_buffer=config.algo not in ("ppo",),
        ),
        SaveNormaliser(),
        Bar(),
    ]
    if config.curve_every > 0:
        callbacks.append(Curve())
    return CallbackList(callbacks)
