"""Training SB3 agents on the pour-gym environments (the logic behind ``train.py``).

A run directory holds everything a run makes: ``config.json`` (the exact arguments and
hyperparameters), ``checkpoints/`` (model, observation normaliser and, for off-policy
algorithms, replay buffer every ``checkpoint_every`` steps), ``progress.csv`` (SB3's
logger), ``curve.csv`` and ``curve.png`` (success and return on the training containers
during training; ``bc_curve.csv`` during behaviour cloning on demonstrations),
``model.zip`` with ``vecnormalize.pkl`` beside it when observations are normalised,
``eval.json`` and ``eval.md``. Running the same command again resumes from
the newest checkpoint until the requested number of steps is reached. With ``--keep-best``,
``best/`` holds the model of the best learning-curve point so far (``point.json``), and
``model.zip`` is that model at the end.

:class:`TrainConfig` is the one definition of the training options: ``train.py`` builds its
command line from its fields.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import re
import sys
from dataclasses import asdict, dataclass, field
from importlib.resources import files
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from pour_gym.agents.evaluate import evaluate_policy, evaluation_table
from pour_gym.agents.rollout import rollout, sb3_policy
from pour_gym.assets import expand_containers
from pour_gym.errors import InputError

# Algorithm name -> "module:class"; imported when used (sb3-contrib is optional).
ALGORITHMS = {
    "sac": "stable_baselines3:SAC",
    "ppo": "stable_baselines3:PPO",
    "td3": "stable_baselines3:TD3",
    "tqc": "sb3_contrib:TQC",
}
NORMALISER = "vecnormalize.pkl"
# The variance that hides an input from the network (ignore_constant_inputs): its
# normalised value is its offset over 10^6, a millionth of what the network reads from
# any other input. Not infinity: SB3 un-normalises terminal observations by multiplying
# by the standard deviation, and 0 x inf is NaN.
HIDDEN_VARIANCE = 1e12
BEST = "best"  # the run's folder of the best learning-curve point (--keep-best)
# Trained models shipped with the package, one folder each (model.zip, config.json, ...).
MODELS = Path(__file__).resolve().parent / "models"


def algorithm(name: str):
    """The SB3 algorithm class of a name in :data:`ALGORITHMS`.

    Raises:
        InputError: an unknown name, or sb3-contrib missing for TQC.
    """
    if name not in ALGORITHMS:
        raise InputError(f"unknown algorithm {name!r}; use one of {', '.join(ALGORITHMS)}")
    module, cls = ALGORITHMS[name].split(":")
    try:
        return getattr(importlib.import_module(module), cls)
    except ImportError:
        raise InputError(
            f"{name} needs the {module.replace('_', '-')} package: pip install "
            f"{module.replace('_', '-')}"
        ) from None


def hyperparameters(env_id: str, algo: str) -> dict:
    """The packaged hyperparameters (``agents/hyperparams.yaml``) for an env and algorithm."""
    table = yaml.safe_load(files("pour_gym.agents").joinpath("hyperparams.yaml").read_text())
    if env_id not in table:
        raise InputError(f"no hyperparameters for {env_id!r}; known: {', '.join(table)}")
    if algo not in table[env_id]:
        raise InputError(f"no {algo!r} hyperparameters for {env_id}; known: {list(table[env_id])}")
    return dict(table[env_id][algo])


def _help(text: str) -> dict:
    return {"help": text}


@dataclass
class TrainConfig:
    """What a training run does (``train.py``'s options are these fields)."""

    env: str = field(default="PourGym/Pour-v0", metadata=_help("environment id"))
    algo: str = field(default="sac", metadata=_help(f"one of {', '.join(ALGORITHMS)}"))
    objects: str = field(
        default="train", metadata=_help("containers to train on: split, name, mesh, or a,b,c")
    )
    timesteps: int = field(default=20_000, metadata=_help("environment steps in total"))
    seed: int = field(default=0, metadata=_help("seed of the algorithm and the environments"))
    obs_mode: str = field(default="features", metadata=_help("features or state"))
    out: str = field(
        default="", metadata=_help("run directory (default runs/<env>_<algo>_<objects>_...)")
    )
    checkpoint_every: int = field(default=5_000, metadata=_help("steps between checkpoints"))
    eval_objects: str = field(default="all", metadata=_help("containers to evaluate on"))
    eval_episodes: int = field(default=5, metadata=_help("evaluation episodes per container"))
    eval_seed: int = field(
        default=10_000, metadata=_help("seed of the first evaluation episode (never trained on)")
    )
    curve_every: int = field(
        default=0, metadata=_help("steps between learning-curve points (0: none)")
    )
    curve_episodes: int = field(default=10, metadata=_help("episodes per learning-curve point"))
    keep_best: bool = field(
        default=False,
        metadata=_help(
            "save as model.zip the learning-curve point with the highest success (then the "
            "lowest amount error, or the highest return), not the last step"
        ),
    )
    env_kwargs: dict = field(
        default_factory=dict, metadata=_help("JSON of more environment arguments")
    )
    overrides: dict = field(
        default_factory=dict, metadata=_help("hyperparameters that replace the YAML's (--set)")
    )

    def run_dir(self) -> Path:
        """The run directory (``out``, or a name made of the run's options)."""
        if self.out:
            return Path(self.out)
        objects = self.objects.replace(",", "+").replace("/", "_")
        name = f"{self.env.split('/')[-1]}_{self.algo}_{objects}_{self.obs_mode}_s{self.seed}"
        return Path("runs") / name


def config_parser(description: str) -> argparse.ArgumentParser:
    """A command line with one option per :class:`TrainConfig` field, plus ``--set``, ``--json``.

    Dict fields take JSON; ``--set key=value`` (repeatable, YAML values) fills ``overrides``.
    """
    p = argparse.ArgumentParser(description=description)
    for f in dataclasses.fields(TrainConfig):
        flag = "--" + f.name.replace("_", "-")
        if f.name == "overrides":
            p.add_argument(
                "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                help="hyperparameter override (repeatable)",
            )  # fmt: skip
            continue
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if isinstance(default, bool):
            p.add_argument(flag, action="store_true", help=f.metadata["help"])
            continue
        kind = json.loads if isinstance(default, dict) else type(default)
        choices = list(ALGORITHMS) if f.name == "algo" else None
        choices = ["features", "state"] if f.name == "obs_mode" else choices
        p.add_argument(flag, type=kind, default=default, choices=choices, help=f.metadata["help"])
    p.add_argument("--json", action="store_true", help="print the evaluation as JSON")
    return p


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The :class:`TrainConfig` of parsed ``config_parser`` arguments."""
    values = {f.name: getattr(args, f.name) for f in dataclasses.fields(TrainConfig)}
    overrides = {}
    for item in values["overrides"]:
        key, sep, value = item.partition("=")
        if not sep:
            raise InputError(f"--set takes key=value, not {item!r}")
        overrides[key] = yaml.safe_load(value)
    values["overrides"] = overrides
    return TrainConfig(**values)


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


def load_run(model_path: str | Path, algo: str | None = None) -> Run:
    """Load ``model.zip`` with the ``config.json`` and ``vecnormalize.pkl`` beside it.

    Args:
        model_path: the model file, or the name of a shipped model (:func:`shipped_models`).
        algo: the algorithm, if there is no ``config.json`` to say it.

    Raises:
        InputError: no such file, or no way to tell the algorithm.
    """
    path = Path(model_path)
    if not path.is_file():
        shipped = MODELS / str(model_path) / "model.zip"
        if not shipped.is_file():
            names = ", ".join(shipped_models()) or "none"
            raise InputError(
                f"no model file {str(model_path)!r}: give a model.zip or a shipped model ({names})"
            )
        path = shipped
    config_path = path.parent / "config.json"
    config = json.loads(config_path.read_text()) if config_path.is_file() else {}
    name = config.get("algo", algo)
    if name is None:
        raise InputError(f"which algorithm made {path.name}? pass --algo ({', '.join(ALGORITHMS)})")
    model = algorithm(name).load(path, device="cpu")
    normaliser = None
    stats = path.parent / NORMALISER
    if stats.is_file():
        import pickle

        with open(stats, "rb") as fh:
            normaliser = pickle.load(fh)  # a VecNormalize without its env
        normaliser.training = False
        normaliser.norm_reward = False
    return Run(model=model, config=config, normaliser=normaliser)


def shipped_models() -> list[str]:
    """The names of the trained models that ship with pour-gym (``agents/models/<name>``)."""
    return sorted(p.parent.name for p in MODELS.glob("*/model.zip"))


def _latest_checkpoint(directory: Path) -> tuple[Path | None, int]:
    best, steps = None, 0
    for path in directory.glob("model_*_steps.zip"):
        n = int(re.search(r"_(\d+)_steps", path.name).group(1))
        if n > steps:
            best, steps = path, n
    return best, steps


def _callbacks(config: TrainConfig, out: Path, total: int, done: int, n_envs: int, env_kwargs):
    """Checkpoints (with the normaliser), a progress bar and the learning curve."""
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback

    class Bar(BaseCallback):
        def _on_training_start(self) -> None:
            self.bar = tqdm(total=total, initial=done, desc="train", file=sys.stderr)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    class Curve(BaseCallback):
        """Success and return of the deterministic policy on the training containers."""

        def __init__(self):
            super().__init__()
            self.next = (done // config.curve_every + 1) * config.curve_every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self.next += config.curve_every
                point = record_curve_point(config, out, self.model, self.training_env, env_kwargs)
                if config.keep_best:
                    keep_if_best(out / BEST, point, self.model, self.training_env)
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


def _rank(point: dict) -> tuple[float, float]:
    """Higher is better: success, then minus the amount error (Pour-v0) or the return."""
    second = -point["amount_error"] if "amount_error" in point else point["return"]
    return (point["success"], second)


def keep_if_best(folder: Path, point: dict, model, venv) -> bool:
    """Save the model and normaliser in ``folder`` if ``point`` beats the one kept there.

    Returns:
        Whether it was kept.
    """
    kept = folder / "point.json"
    if kept.is_file() and _rank(json.loads(kept.read_text())) >= _rank(point):
        return False
    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / "model.zip")
    save_normaliser(venv, folder)
    kept.write_text(json.dumps(point) + "\n")
    return True


def save_normaliser(venv, folder: Path, steps: int | None = None) -> None:
    """Save a ``VecNormalize``'s statistics (nothing for other vector envs)."""
    from stable_baselines3.common.vec_env import VecNormalize

    if isinstance(venv, VecNormalize):
        name = NORMALISER if steps is None else f"vecnormalize_{steps}_steps.pkl"
        venv.save(str(folder / name))


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

    ``x`` is the point's abscissa (name, value): the model's environment steps by default,
    ``("bc_steps", k)`` for the behaviour-cloning curve (``bc_curve.csv``).
    """
    import gymnasium as gym
    from stable_baselines3.common.vec_env import VecNormalize

    normaliser = venv if isinstance(venv, VecNormalize) else None
    run = Run(model=model, config={}, normaliser=normaliser)
    env = gym.make(config.env, **env_kwargs)
    episodes = [
        rollout(env, sb3_policy(run), seed=config.eval_seed + 500_000 + k)
        for k in range(config.curve_episodes)
    ]
    env.close()
    key, value = x if x is not None else ("timesteps", int(model.num_timesteps))
    point = {
        key: int(value),
        "success": float(np.mean([e.info["is_success"] for e in episodes])),
        "return": float(np.mean([e.reward for e in episodes])),
    }
    if "poured" in episodes[0].info:
        point["amount_error"] = float(
            np.mean([abs(e.info["poured"] - e.info["target_amount"]) for e in episodes])
        )
        point["spilled"] = float(np.mean([e.info["spilled"] for e in episodes]))
    path = out / name
    new = not path.is_file()
    with open(path, "a") as fh:
        if new:
            fh.write(",".join(point) + "\n")
        fh.write(",".join(f"{v:g}" for v in point.values()) + "\n")
    return point


def _read_curve(path: Path) -> dict[str, np.ndarray] | None:
    """A learning curve's CSV as columns (None if missing or empty)."""
    import csv

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


def plot_curve(out: Path, title: str) -> Path | None:
    """``curve.png``: success and return against behaviour-cloning and environment steps.

    One row per curve the run has: ``bc_curve.csv`` (during behaviour cloning on the
    demonstrations, against gradient steps) and ``curve.csv`` (during training, against
    environment steps). For Pour-v0, a second panel shows the amount error and the spill.
    """
    curves = [
        (data, key, label)
        for name, key, label in (
            ("bc_curve.csv", "bc_steps", "behaviour-cloning gradient steps"),
            ("curve.csv", "timesteps", "environment steps"),
        )
        if (data := _read_curve(out / name)) is not None
    ]
    if not curves:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pour = any(
        "amount_error" in d and not np.all(np.isnan(d["amount_error"])) for d, _, _ in curves
    )
    fig, axes = plt.subplots(
        len(curves), 2 if pour else 1, figsize=(11 if pour else 7, 4 * len(curves)),
        squeeze=False,
    )  # fmt: skip
    for row, (data, key, label) in enumerate(curves):
        ax = axes[row, 0]
        steps = data[key]
        ax.plot(steps, data["success"], "o-", label="success rate")
        ax.set_xlabel(label)
        ax.set_ylabel("success rate (deterministic policy)")
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
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    png = out / "curve.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def recipe_curriculum(params: dict) -> dict | None:
    """Take the curriculum keys out of a recipe's parameters.

    ``start_near_target``: the share of episodes that start over the target;
    ``fill_margin``: [lo, hi] particles of fill beyond the target amount.
    """
    curriculum = {}
    if "start_near_target" in params:
        curriculum["near_target"] = float(params.pop("start_near_target"))
    if "fill_margin" in params:
        curriculum["fill_margin"] = [int(m) for m in params.pop("fill_margin")]
    return curriculum or None


def recipe_demonstrations(params: dict) -> dict | None:
    """Take the ``demonstrations`` key out of a recipe's parameters.

    ``demonstrations: {episodes: n, share: s, bc_steps: k, bc_weight: w, noise: sigma,
    expert: {...}, ignore_constant: true, hide: [names]}``: record n episodes of the
    scripted policy (``expert``: its arguments; its executed actions with Gaussian noise of
    standard deviation sigma, one value or one per action, its clean actions as the
    labels), keep them as a share s of every replay batch, pre-train the actor on them for
    k steps and keep a behaviour-cloning term of weight w in its every update
    (:mod:`pour_gym.agents.demonstrations`); with ``ignore_constant`` the network is blind
    to every input the demonstrations never vary, and to the inputs ``hide`` names
    (:func:`ignore_constant_inputs`). Off-policy algorithms with an actor (SAC, TQC) only.
    """
    demos = params.pop("demonstrations", None)
    if not demos:
        return None
    keys = {"episodes", "share", "bc_steps", "bc_weight", "noise", "expert", "ignore_constant",
            "hide"}  # fmt: skip
    if set(demos) - keys:
        unknown = sorted(set(demos) - keys)
        raise InputError(f"unknown demonstrations keys {unknown}; use {', '.join(sorted(keys))}")
    noise = demos.get("noise", 0.0)
    return {
        "episodes": int(demos.get("episodes", 50)),
        "share": float(demos.get("share", 0.5)),
        "bc_steps": int(demos.get("bc_steps", 0)),
        "bc_weight": float(demos.get("bc_weight", 0.0)),
        "noise": [float(n) for n in noise] if isinstance(noise, list) else float(noise),
        "expert": dict(demos.get("expert") or {}),
        "ignore_constant": bool(demos.get("ignore_constant", False)),
        "hide": [str(name) for name in demos.get("hide") or []],
    }


def ignore_constant_inputs(normaliser, observations: np.ndarray, names=None, also=()) -> list:
    """Blind a ``VecNormalize`` (and so the network behind it) to inputs that never vary.

    Trained on one cup, the containers' rim radii and heights (or, from raw state, their
    bounding boxes) are constants: the network cannot learn what they mean, and on another
    cup their difference is an input it never saw, which moves its actions arbitrarily.
    Such an input's variance is set to :data:`HIDDEN_VARIANCE`, which scales it to about
    nothing whatever it is; the statistics are saved with the normaliser, so evaluation
    sees the same.

    Args:
        normaliser: a ``VecNormalize`` whose statistics are fixed (``training=False``).
        observations: (n, obs_dim) the observations the statistics came from.
        names: the inputs' names, for the returned list (indices if None).
        also: names of inputs to hide as well, where ``names`` has them.

    Returns:
        The names (or indices) of the inputs left out.
    """
    spread = observations.max(axis=0) - observations.min(axis=0)
    constant = spread <= 1e-6 * np.maximum(np.abs(observations).max(axis=0), 1.0)
    if names is not None:
        constant |= np.isin(np.asarray(names), list(also))
    hidden = np.flatnonzero(constant)
    normaliser.obs_rms.var[hidden] = HIDDEN_VARIANCE
    return [names[k] if names is not None else int(k) for k in hidden]


def start_from_demonstrations(
    config: TrainConfig, model, venv, env_kwargs: dict, demos_cfg: dict, curriculum, out: Path
) -> dict:
    """Record the scripted policy's episodes, put them in the replay buffer, pre-train.

    The observation normaliser starts from the demonstrations' statistics, so that the
    pre-trained actor sees the inputs it will see in training.

    Returns:
        What was done (written to ``demonstrations.json`` in the run directory).
    """
    from stable_baselines3.common.vec_env import VecNormalize

    from pour_gym.agents.demonstrations import (
        collect_demonstrations,
        pretrain_actor,
        regularise_actor,
    )

    curriculum = curriculum or {}
    demos = collect_demonstrations(
        config.env,
        env_kwargs,
        demos_cfg["episodes"],
        seed=900_000 + 1000 * config.seed,
        near_target=curriculum.get("near_target", 0.0),
        fill_margin=curriculum.get("fill_margin"),
        noise=demos_cfg.get("noise", 0.0),
        expert=demos_cfg.get("expert"),
    )
    model.replay_buffer.add_demonstrations(demos)
    normaliser = venv if isinstance(venv, VecNormalize) else None
    if normaliser is not None and normaliser.norm_obs:
        # The normaliser keeps the demonstrations' statistics: were they to follow the
        # learner's own (first random) steps, the pre-trained actor would see other
        # inputs than it was fitted on (measured on the red cup: 10/10 successes straight
        # after pre-training with these statistics and the recipe's variance floor; 0/6
        # when 2000 random steps had moved them, with SB3's default floor).
        normaliser.obs_rms.update(demos.observations)
        normaliser.training = False
    ignored = []
    if demos_cfg.get("ignore_constant") or demos_cfg.get("hide"):
        if normaliser is None or not normaliser.norm_obs:
            raise InputError(
                "demonstrations' ignore_constant and hide need normalize: {norm_obs: true}"
            )
        names = venv.get_attr("obs_names")[0]
        ignored = ignore_constant_inputs(
            normaliser, demos.observations, names, also=demos_cfg.get("hide", ())
        )
    mse = None
    if demos_cfg["bc_steps"] > 0:
        # The learning curve of behaviour cloning: six points (bc_curve.csv), with the
        # training curve's episodes, when the run draws one.
        every = max(demos_cfg["bc_steps"] // 6, 1) if config.curve_every > 0 else 0

        def point(step: int) -> None:
            record_curve_point(
                config, out, model, venv, env_kwargs, "bc_curve.csv", ("bc_steps", step)
            )

        mse = pretrain_actor(
            model, demos, normaliser, steps=demos_cfg["bc_steps"], callback=point, every=every
        )
    if demos_cfg["bc_weight"] > 0:
        regularise_actor(model, demos, normaliser, weight=demos_cfg["bc_weight"])
    record = {
        **demos_cfg,
        "transitions": len(demos),
        "episodes_succeeded": demos.successes,
        "bc_action_mse": mse,
        "ignored_inputs": ignored,
    }
    (out / "demonstrations.json").write_text(json.dumps(record, indent=2) + "\n")
    return record


def make_training_env(
    config: TrainConfig,
    n_envs: int,
    normalize: dict | None,
    env_kwargs: dict,
    curriculum: dict | None = None,
):
    """The vector env: subprocess workers when ``n_envs > 1``, normalised if asked.

    ``curriculum``: arguments of :class:`~pour_gym.agents.curriculum.TrainingStarts`
    (``near_target``, ``fill_margin``) for Pour-v0's training episodes, or None.
    """
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    from pour_gym.agents.curriculum import TrainingStarts

    wrap = {}
    if curriculum:
        wrap = {"wrapper_class": TrainingStarts, "wrapper_kwargs": dict(curriculum)}
    if n_envs > 1:
        venv = make_vec_env(
            config.env, n_envs=n_envs, seed=config.seed, env_kwargs=env_kwargs,
            vec_env_cls=SubprocVecEnv, vec_env_kwargs={"start_method": "forkserver"}, **wrap,
        )  # fmt: skip
    else:
        venv = make_vec_env(
            config.env, n_envs=1, seed=config.seed, env_kwargs=env_kwargs,
            vec_env_cls=DummyVecEnv, **wrap,
        )  # fmt: skip
    if normalize:
        venv = VecNormalize(venv, **normalize)
    return venv


def train(config: TrainConfig) -> dict:
    """Train (or resume) an SB3 agent, save it, and evaluate it on every container.

    Returns:
        The evaluation document (also written to ``eval.json``), with ``model`` and
        ``timesteps``.
    """
    import gymnasium as gym
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import VecNormalize

    import pour_gym  # noqa: F401 - registers the environments

    cls = algorithm(config.algo)
    if config.timesteps <= 0:
        raise InputError(f"--timesteps must be positive, not {config.timesteps}")
    if config.keep_best and config.curve_every <= 0:
        raise InputError("--keep-best picks among learning-curve points: add --curve-every N")
    if config.env not in gym.registry:
        raise InputError(f"unknown environment {config.env!r}")
    params = {**hyperparameters(config.env, config.algo), **config.overrides}
    n_envs = int(params.pop("n_envs", 1))
    policy = params.pop("policy", "MlpPolicy")
    normalize = params.pop("normalize", None)
    # The recipe's environment arguments (reward weights, ...); the run's own win.
    recipe_env = params.pop("env_kwargs", {}) or {}
    torch_threads = int(params.pop("torch_threads", 1))
    curriculum = recipe_curriculum(params)
    demos_cfg = recipe_demonstrations(params)
    if demos_cfg:
        if config.algo not in ("sac", "tqc"):
            raise InputError(f"demonstrations need sac or tqc, not {config.algo}")
        from pour_gym.agents.demonstrations import DemoReplayBuffer

        params["replay_buffer_class"] = DemoReplayBuffer
        params["replay_buffer_kwargs"] = {"demo_share": demos_cfg["share"]}
    train_objects = list(expand_containers(config.objects))
    out = config.run_dir()
    ckpt_dir = out / "checkpoints"
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(
        json.dumps(
            {
                **asdict(config),
                "out": str(out),
                "hyperparameters": {k: v for k, v in params.items() if k != "replay_buffer_class"},
                "demonstrations": demos_cfg,
                "n_envs": n_envs,
                "policy": policy,
                "normalize": normalize,
                "curriculum": curriculum,
                # What the environments were made with (recipe and run): evaluate uses it.
                "env_kwargs": {**recipe_env, **config.env_kwargs},
            },
            indent=2,
        )
    )
    import torch

    # The learner and the environments' fluid share the cores: one thread for torch.
    torch.set_num_threads(torch_threads)
    env_kwargs = {
        "objects": train_objects,
        "obs_mode": config.obs_mode,
        **recipe_env,
        **config.env_kwargs,
    }
    venv = make_training_env(config, n_envs, normalize, env_kwargs, curriculum)
    checkpoint, done = _latest_checkpoint(ckpt_dir)
    if checkpoint is None:
        # A fresh run owns its curves: a folder trained into before (a shipped model's, say)
        # must not lend it old points.
        for stale in ("curve.csv", "bc_curve.csv", f"{BEST}/point.json"):
            (out / stale).unlink(missing_ok=True)
    if checkpoint is not None:
        stats = ckpt_dir / f"vecnormalize_{done}_steps.pkl"
        if normalize and stats.is_file():
            venv = VecNormalize.load(str(stats), venv.venv)
        model = cls.load(checkpoint, env=venv, seed=config.seed, device="cpu")
        buffer = ckpt_dir / f"model_replay_buffer_{done}_steps.pkl"
        if buffer.is_file() and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(buffer)
        demos = getattr(getattr(model, "replay_buffer", None), "demonstrations", None)
        if demos_cfg and demos_cfg["bc_weight"] > 0 and demos is not None:
            # The behaviour-cloning term lives in the actor's optimiser, not in the save.
            from pour_gym.agents.demonstrations import regularise_actor

            normaliser = venv if isinstance(venv, VecNormalize) else None
            regularise_actor(model, demos, normaliser, weight=demos_cfg["bc_weight"])
    else:
        model = cls(policy, venv, seed=config.seed, verbose=0, device="cpu", **params)
        if demos_cfg:
            start_from_demonstrations(config, model, venv, env_kwargs, demos_cfg, curriculum, out)
    model.set_logger(configure(str(out), ["csv"]))
    remaining = config.timesteps - done
    if remaining > 0:
        callbacks = _callbacks(config, out, remaining + done, done, n_envs, env_kwargs)
        model.learn(remaining, callback=callbacks, reset_num_timesteps=checkpoint is None)
        # The finished run is a checkpoint too: running the command again only evaluates.
        model.save(ckpt_dir / f"model_{model.num_timesteps}_steps.zip")
        save_normaliser(venv, ckpt_dir, model.num_timesteps)
    model.save(out / "model.zip")
    save_normaliser(venv, out)
    venv.close()
    best = out / BEST
    if config.keep_best and (best / "model.zip").is_file():
        # The model is the best learning-curve point's (best/point.json says which).
        import shutil

        for name in ("model.zip", NORMALISER):
            if (best / name).is_file():
                shutil.copyfile(best / name, out / name)
    plot_curve(out, f"{config.env}, {config.algo}, {config.obs_mode}, {config.objects}")
    run = load_run(out / "model.zip")
    result = evaluate_policy(
        sb3_policy(run),
        config.env,
        expand_containers(config.eval_objects),
        config.eval_episodes,
        seed=config.eval_seed,
        env_kwargs={"obs_mode": config.obs_mode, **recipe_env, **config.env_kwargs},
        trained_on=train_objects,
    )
    result.update(model=str(out / "model.zip"), timesteps=config.timesteps, algo=config.algo)
    (out / "eval.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "eval.md").write_text(evaluation_table(result) + "\n")
    return result
