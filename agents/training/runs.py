"""Run directories: trained models with their config and normaliser, checkpoints, the best.

A run directory holds everything a run makes: ``config.json`` (the exact arguments and
recipe), ``checkpoints/`` (model, observation normaliser and, for off-policy algorithms,
replay buffer every ``checkpoint_every`` steps), ``progress.csv`` (SB3's logger),
``curve.csv`` / ``bc_curve.csv`` and ``curve.png`` (:mod:`~pour_gym.agents.training.curves`),
``model.zip`` with ``vecnormalize.pkl`` beside it when observations are normalised, and
``eval.json`` / ``eval.md``. With ``--keep-best``, ``best/`` holds the model of the best
learning-curve point so far (``point.json``).
"""

from __future__ import annotations

import json
import pickle
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pour_gym.agents.training.config import ALGORITHMS, algorithm
from pour_gym.agents.training.moved_modules import importable_old_paths
from pour_gym.assets import expand_containers
from pour_gym.envs import Task
from pour_gym.errors import InputError

NORMALISER = "vecnormalize.pkl"
BEST = "best"  # the run's folder of the best learning-curve point (--keep-best)
# Trained models shipped with the package, one folder each (model.zip, config.json, ...).
MODELS = Path(__file__).resolve().parents[1] / "models"


@dataclass
class Run:
    """A trained model with what it needs to act: its config and observation normaliser.

    Attributes:
        model: the SB3 algorithm.
        config: the run's ``config.json`` (empty if there was none).
        normaliser: a ``VecNormalize`` with the training's statistics, or None.
    """

    model: object
    config: dict
    normaliser: object | None = None

    def env_kwargs(self) -> dict:
        """The environment arguments the model acts in (its observation mode, its run's)."""
        return {
            "obs_mode": self.config.get("obs_mode", "features"),
            **self.config.get("env_kwargs", {}),
        }

    def trained_on(self) -> list[str]:
        """The containers the model was trained on."""
        return list(expand_containers(self.config.get("objects") or "train"))

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        """An observation as the model saw them in training."""
        if self.normaliser is None:
            return obs
        return self.normaliser.normalize_obs(obs)


def shipped_models() -> list[str]:
    """The names of the trained models that ship with pour-gym (``agents/models/<name>``)."""
    return sorted(p.parent.name for p in MODELS.glob("*/model.zip"))


def load_run(model_path: str | Path, algo: str | None = None) -> Run:
    """Load ``model.zip`` with the ``config.json`` and ``vecnormalize.pkl`` beside it.

    Args:
        model_path: the model file (a run's ``model.zip``, a checkpoint
            ``checkpoints/model_<steps>_steps.zip`` or ``best/model.zip``, each loaded
            with its own normaliser and the run's ``config.json``), a run folder holding
            ``model.zip``, or the name of a shipped model (:func:`shipped_models`).
        algo: the algorithm, if there is no ``config.json`` to say it.

    Raises:
        InputError: no such file, no way to tell the algorithm, or a model trained on
            normalised observations without its normaliser.
    """
    given = Path(model_path)
    # The file itself, a run folder as train.py --out wrote it, or a shipped model's folder.
    candidates = (given, given / "model.zip", MODELS / str(model_path) / "model.zip")
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        names = ", ".join(shipped_models()) or "none"
        raise InputError(
            f"no model file {str(model_path)!r}: give a model.zip, a run folder holding "
            f"one, or a shipped model ({names})"
        )
    # A checkpoint (checkpoints/model_<N>_steps.zip) or a kept best (best/model.zip) has
    # its run's config.json one folder up, and a checkpoint its own steps' normaliser.
    config_path = next(
        (p for p in (path.parent / "config.json", path.parent.parent / "config.json")
         if p.is_file()), None,
    )  # fmt: skip
    config = json.loads(config_path.read_text()) if config_path is not None else {}
    steps = checkpoint_steps(path)
    stats = (
        checkpoint_file(path.parent, steps, "normaliser")
        if steps is not None
        else path.parent / NORMALISER
    )
    if config.get("normalize") and not stats.is_file():
        # Acting on raw observations, a model trained on normalised ones is another policy.
        raise InputError(
            f"{path} was trained on normalised observations and {stats.name} is not beside "
            "it: copy the run's normaliser next to the model"
        )
    name = config.get("algo", algo)
    if name is None:
        raise InputError(f"which algorithm made {path.name}? pass --algo ({', '.join(ALGORITHMS)})")
    if MODELS.resolve() not in path.resolve().parents:
        # A model file is a zip of pickles and its normaliser a pickle: loading one runs
        # whatever code its author put in it. Said once per process (Python's default
        # filter shows a warning once per place).
        warnings.warn(
            f"loading {path} unpickles it (and {NORMALISER} beside it): load only models "
            "from sources you trust",
            UserWarning,
            stacklevel=2,
        )
    importable_old_paths()  # a model saved before the agents were grouped
    model = algorithm(name).load(path, device="cpu")
    normaliser = None
    if stats.is_file():
        with open(stats, "rb") as fh:
            normaliser = pickle.load(fh)  # a VecNormalize without its env
        normaliser.training = False
        normaliser.norm_reward = False
    return Run(model=model, config=config, normaliser=normaliser)


def checkpoint_file(folder: Path, steps: int, kind: str = "model") -> Path:
    """A checkpoint folder's file of ``steps`` environment steps.

    Args:
        folder: the run's ``checkpoints`` folder.
        steps: the checkpoint's environment steps.
        kind: ``"model"`` (SB3's ``model_<steps>_steps.zip``), ``"normaliser"`` (its
            ``VecNormalize`` statistics) or ``"replay_buffer"`` (an off-policy learner's).
    """
    names = {
        "model": f"model_{steps}_steps.zip",
        "normaliser": f"vecnormalize_{steps}_steps.pkl",
        "replay_buffer": f"model_replay_buffer_{steps}_steps.pkl",
    }
    return folder / names[kind]


def checkpoint_steps(path: str | Path) -> int | None:
    """The env steps of a checkpoint file (SB3's ``model_<steps>_steps.zip``), else None."""
    steps = re.fullmatch(r"model_(\d+)_steps\.zip", Path(path).name)
    return int(steps.group(1)) if steps else None


def latest_checkpoint(directory: Path) -> tuple[Path | None, int]:
    """The newest ``model_<steps>_steps.zip`` in a checkpoint folder, and its steps."""
    best, steps = None, 0
    for path in directory.glob("model_*_steps.zip"):
        n = checkpoint_steps(path) or 0
        if n > steps:
            best, steps = path, n
    return best, steps


def save_normaliser(venv, folder: Path, steps: int | None = None) -> None:
    """Save a ``VecNormalize``'s statistics (nothing for other vector envs)."""
    from stable_baselines3.common.vec_env import VecNormalize

    if isinstance(venv, VecNormalize):
        if steps is not None:
            venv.save(str(checkpoint_file(folder, steps, "normaliser")))
        else:
            venv.save(str(folder / NORMALISER))


def rank_point(point: dict, task: Task) -> tuple[float, float]:
    """A learning-curve point's rank, higher is better.

    Success first, then minus the amount error (pouring) or the return.
    """
    return (point["success"], -point["amount_error"] if task.pours else point["return"])


def keep_if_best(folder: Path, point: dict, model, venv, task: Task) -> bool:
    """Save the model and normaliser in ``folder`` if ``point`` beats the one kept there.

    Args:
        folder: where the best point's model, normaliser and ``point.json`` are kept.
        point: a learning-curve point (the task's metrics).
        model: the SB3 algorithm.
        venv: the training's vector env (its normaliser is saved, if it is one).
        task: the env's task (what ranks second after success).

    Returns:
        Whether it was kept.
    """
    kept = folder / "point.json"
    if kept.is_file() and rank_point(json.loads(kept.read_text()), task) >= rank_point(point, task):
        return False
    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / "model.zip")
    save_normaliser(venv, folder)
    kept.write_text(json.dumps(point) + "\n")
    return True
