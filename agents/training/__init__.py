"""Training SB3 agents on the pour-gym environments (``train.py`` and ``pour-gym train``).

- :mod:`~pour_gym.agents.training.config`: :class:`TrainConfig`, the options of a run and
  the command line built from it; the algorithms.
- :mod:`~pour_gym.agents.training.recipes`: ``agents/hyperparams.yaml``'s entries, their
  keys declared (the training's, the algorithm's, env wrappers).
- :mod:`~pour_gym.agents.training.runs`: run directories, trained models with their
  normaliser (:func:`load_run`), checkpoints, the models that ship with pour-gym.
- :mod:`~pour_gym.agents.training.curves`: learning curves and the run's callbacks.
- :mod:`~pour_gym.agents.training.warm_start`: a warm start from the expert's demonstrations.
- :mod:`~pour_gym.agents.training.curriculum`, :mod:`~pour_gym.agents.training.schedule`,
  :mod:`~pour_gym.agents.training.noise`: what a recipe may change over a run (how
  episodes start, an env or algorithm argument by step, the action noise).
- :mod:`~pour_gym.agents.training.loop`: :func:`train`.

Running the same command again resumes from the newest checkpoint until the requested
number of steps is reached.
"""

from pour_gym.agents.training.config import (
    ALGORITHMS,
    TrainConfig,
    algorithm,
    config_from_args,
    config_parser,
)
from pour_gym.agents.training.loop import env_arguments, make_training_env, train
from pour_gym.agents.training.recipes import DemoConfig, Recipe, load_hyperparameters, load_recipe
from pour_gym.agents.training.runs import MODELS, Run, keep_if_best, load_run, shipped_models

__all__ = [
    "ALGORITHMS",
    "MODELS",
    "DemoConfig",
    "Recipe",
    "Run",
    "TrainConfig",
    "algorithm",
    "config_from_args",
    "config_parser",
    "env_arguments",
    "keep_if_best",
    "load_hyperparameters",
    "load_recipe",
    "load_run",
    "make_training_env",
    "shipped_models",
    "train",
]
