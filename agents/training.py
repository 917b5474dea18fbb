"""Training SB3 agents on the pour-gym environments (the logic behind ``train.py``).

A run directory holds everything a run makes: ``config.json`` (the exact arguments and
hyperparameters), ``checkpoints/`` (model and, for off-policy algorithms, replay buffer
every ``checkpoint_every`` steps), ``progress.csv`` (SB3's logger; TensorBoard events too
when tensorboard is installed), ``model.zip`` and ``eval.json``. Running the same command
again resumes from the newest checkpoint until the requested number of steps is reached.
"""

from __future__ import annotations

import json
import re
import sys
from dataclasses import asdict, dataclass, field
from importlib.resources import files
from pathlib import Path

import yaml
from tqdm import tqdm

from pour_gym.agents.evaluate import evaluate_policy, evaluation_table, sb3_policy
from pour_gym.assets import expand_containers
from pour_gym.errors import InputError

ALGOS = ("sac", "ppo", "td3")


def hyperparameters(env_id: str, algo: str) -> dict:
    """The packaged hyperparameters (``agents/hyperparams.yaml``) for an env and algorithm."""
    table = yaml.safe_load(files("pour_gym.agents").joinpath("hyperparams.yaml").read_text())
    if env_id not in table:
        raise InputError(f"no hyperparameters for {env_id!r}; known: {', '.join(table)}")
    if algo not in table[env_id]:
        raise InputError(f"no {algo!r} hyperparameters for {env_id}; known: {list(table[env_id])}")
    return dict(table[env_id][algo])


@dataclass
class TrainConfig:
    """What a training run does.

    Attributes:
        env: environment id.
        algo: ``sac``, ``ppo`` or ``td3``.
        objects: containers to train on (split, name, path or list).
        timesteps: environment steps in total (over all vectorised copies).
        seed: seed of the algorithm and the environments.
        obs_mode: ``features`` or ``state``.
        out: run directory.
        checkpoint_every: steps between checkpoints.
        eval_objects: containers to evaluate on at the end.
        eval_episodes: episodes per evaluated object.
        env_kwargs: more environment arguments (e.g. a smaller ``source_particles``).
        overrides: hyperparameters that replace the YAML file's.
    """

    env: str = "PourGym/Pour-v0"
    algo: str = "sac"
    objects: str | list[str] = "train"
    timesteps: int = 20_000
    seed: int = 0
    obs_mode: str = "features"
    out: str = "runs/run"
    checkpoint_every: int = 5_000
    eval_objects: str | list[str] = "all"
    eval_episodes: int = 5
    env_kwargs: dict = field(default_factory=dict)
    overrides: dict = field(default_factory=dict)


class _ProgressBar:
    """A tqdm bar over environment steps, as an SB3 callback (no rich needed)."""

    def __new__(cls, total: int, start: int):
        from stable_baselines3.common.callbacks import BaseCallback

        class Bar(BaseCallback):
            def _on_training_start(self) -> None:
                self.bar = tqdm(total=total, initial=start, desc="train", file=sys.stderr)

            def _on_step(self) -> bool:
                self.bar.update(self.training_env.num_envs)
                return True

            def _on_training_end(self) -> None:
                self.bar.close()

        return Bar()


def _latest_checkpoint(directory: Path) -> tuple[Path | None, int]:
    best, steps = None, 0
    for path in directory.glob("model_*_steps.zip"):
        n = int(re.search(r"_(\d+)_steps", path.name).group(1))
        if n > steps:
            best, steps = path, n
    return best, steps


def train(config: TrainConfig) -> dict:
    """Train (or resume) an SB3 agent, save it, and evaluate it on every container.

    Returns:
        The evaluation document (also written to ``eval.json``), with ``model`` and
        ``timesteps``.
    """
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC, TD3
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure

    import pour_gym  # noqa: F401 - registers the environments

    if config.algo not in ALGOS:
        raise InputError(f"unknown algorithm {config.algo!r}; use one of {', '.join(ALGOS)}")
    if config.timesteps <= 0:
        raise InputError(f"--timesteps must be positive, not {config.timesteps}")
    if config.env not in gym.registry:
        raise InputError(f"unknown environment {config.env!r}")
    params = {**hyperparameters(config.env, config.algo), **config.overrides}
    n_envs = int(params.pop("n_envs", 1))
    policy = params.pop("policy", "MlpPolicy")
    train_objects = list(expand_containers(config.objects))
    out = Path(config.out)
    ckpt_dir = out / "checkpoints"
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(
        json.dumps({**asdict(config), "hyperparameters": params, "n_envs": n_envs}, indent=2)
    )
    env_kwargs = {"objects": train_objects, "obs_mode": config.obs_mode, **config.env_kwargs}
    venv = make_vec_env(config.env, n_envs=n_envs, seed=config.seed, env_kwargs=env_kwargs)
    cls = {"sac": SAC, "ppo": PPO, "td3": TD3}[config.algo]
    checkpoint, done = _latest_checkpoint(ckpt_dir)
    if checkpoint is not None:
        model = cls.load(checkpoint, env=venv, seed=config.seed)
        buffer = ckpt_dir / f"model_replay_buffer_{done}_steps.pkl"
        if buffer.is_file() and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(buffer)
    else:
        model = cls(policy, venv, seed=config.seed, verbose=0, **params)
    formats = ["csv"]
    try:
        import tensorboard  # noqa: F401

        formats.append("tensorboard")
    except ImportError:
        pass
    model.set_logger(configure(str(out), formats))
    remaining = config.timesteps - done
    if remaining > 0:
        callbacks = CallbackList(
            [
                CheckpointCallback(
                    max(config.checkpoint_every // n_envs, 1),
                    str(ckpt_dir),
                    name_prefix="model",
                    save_replay_buffer=config.algo != "ppo",
                ),
                _ProgressBar(remaining + done, done),
            ]
        )
        model.learn(remaining, callback=callbacks, reset_num_timesteps=checkpoint is None)
        # The finished run is a checkpoint too: running the command again only evaluates.
        model.save(ckpt_dir / f"model_{model.num_timesteps}_steps.zip")
    model.save(out / "model.zip")
    venv.close()
    result = evaluate_policy(
        sb3_policy(model),
        config.env,
        expand_containers(config.eval_objects),
        config.eval_episodes,
        env_kwargs={"obs_mode": config.obs_mode, **config.env_kwargs},
        trained_on=train_objects,
    )
    result.update(model=str(out / "model.zip"), timesteps=config.timesteps, algo=config.algo)
    (out / "eval.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "eval.md").write_text(evaluation_table(result) + "\n")
    return result
