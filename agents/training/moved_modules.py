"""Old import paths of the agents' modules, for runs saved before the agents were grouped.

A saved model names the classes it pickled by their module (an off-policy model trained
from demonstrations names ``pour_gym.agents.demonstrations.DemoReplayBuffer``), and a run's
``config.json`` names its env wrappers (``pour_gym.agents.curriculum.TrainingStarts``).
The modules moved into ``policies/``, ``training/``, ``evaluation/`` and ``thesis/`` on
2026-12-04; :func:`importable_old_paths` makes each old path import the module that is
there now, before a model or a wrapper is loaded by name.
"""

from __future__ import annotations

import importlib
import sys

MOVED = {
    "pour_gym.agents.curriculum": "pour_gym.agents.training.curriculum",
    "pour_gym.agents.demonstrations": "pour_gym.agents.training.demonstrations",
    "pour_gym.agents.residual": "pour_gym.agents.policies.residual",
    "pour_gym.agents.scripted": "pour_gym.agents.policies.scripted",
}


def importable_old_paths() -> None:
    """Make every old module path in ``MOVED`` import its module's new place (idempotent)."""
    for old, new in MOVED.items():
        if old not in sys.modules:
            sys.modules[old] = importlib.import_module(new)
