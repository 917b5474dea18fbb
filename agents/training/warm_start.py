"""Starting an off-policy learner from the scripted expert's demonstrations.

A recipe's ``demonstrations`` key (:class:`~pour_gym.agents.training.recipes.DemoConfig`)
records the expert in the training env, puts its transitions in the replay buffer, fits
the observation normaliser to them, hides inputs that carry one container's size, and
behaviour-clones the actor (:mod:`pour_gym.agents.training.demonstrations`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from pour_gym.agents.training.config import TrainConfig
from pour_gym.agents.training.curves import record_curve_point
from pour_gym.agents.training.recipes import DemoConfig
from pour_gym.errors import InputError

# The variance that hides an input from the network (ignore_constant_inputs): its
# normalised value is its offset over 10^6, a millionth of what the network reads from
# any other input. Not infinity: SB3 un-normalises terminal observations by multiplying
# by the standard deviation, and 0 x inf is NaN.
HIDDEN_VARIANCE = 1e12
# The demonstrations' first episode's seed, per training seed (never an evaluation seed).
DEMO_SEED, DEMO_SEED_STRIDE = 900_000, 1000


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
    config: TrainConfig,
    model,
    venv,
    env_kwargs: dict,
    demos_cfg: DemoConfig,
    wrapper: Callable | None,
    out: Path,
) -> dict:
    """Record the scripted policy's episodes, put them in the replay buffer, pre-train.

    The observation normaliser starts from the demonstrations' statistics, so that the
    pre-trained actor sees the inputs it will see in training.

    Args:
        config: the run's config.
        model: the SB3 algorithm (SAC or TQC, with a
            :class:`~pour_gym.agents.training.demonstrations.DemoReplayBuffer`).
        venv: the training's vector env.
        env_kwargs: the training env's arguments.
        demos_cfg: the recipe's ``demonstrations``.
        wrapper: the recipe's env wrappers (the demonstrations start as training does).
        out: the run directory.

    Returns:
        What was done (written to ``demonstrations.json`` in the run directory).
    """
    from stable_baselines3.common.vec_env import VecNormalize

    from pour_gym.agents.training.demonstrations import (
        collect_demonstrations,
        pretrain_actor,
        regularise_actor,
    )

    demos = collect_demonstrations(
        config.env,
        env_kwargs,
        demos_cfg.episodes,
        seed=DEMO_SEED + DEMO_SEED_STRIDE * config.seed,
        wrapper=wrapper,
        noise=demos_cfg.noise,
        expert=demos_cfg.expert,
    )
    model.replay_buffer.add_demonstrations(demos)
    normaliser = venv if isinstance(venv, VecNormalize) else None
    if normaliser is not None and normaliser.norm_obs:
        # The normaliser keeps the demonstrations' statistics: were they to follow the
        # learner's own (first random) steps, the pre-trained actor would see other
        # inputs than it was fitted on (docs: learning Pour-v0).
        normaliser.obs_rms.update(demos.observations)
        normaliser.training = False
    ignored = []
    if demos_cfg.ignore_constant or demos_cfg.hide:
        if normaliser is None or not normaliser.norm_obs:
            raise InputError(
                "demonstrations' ignore_constant and hide need normalize: {norm_obs: true}"
            )
        names = venv.get_attr("obs_names")[0]
        ignored = ignore_constant_inputs(normaliser, demos.observations, names, also=demos_cfg.hide)
    mse = None
    if demos_cfg.bc_steps > 0:
        # The learning curve of behaviour cloning: six points (bc_curve.csv), with the
        # training curve's episodes, when the run draws one.
        every = max(demos_cfg.bc_steps // 6, 1) if config.curve_every > 0 else 0

        def point(step: int) -> None:
            record_curve_point(
                config, out, model, venv, env_kwargs, "bc_curve.csv", ("bc_steps", step)
            )

        mse = pretrain_actor(
            model, demos, normaliser, steps=demos_cfg.bc_steps, callback=point, every=every
        )
    if demos_cfg.bc_weight > 0:
        regularise_actor(model, demos, normaliser, weight=demos_cfg.bc_weight)
    record = {
        **dataclasses.asdict(demos_cfg),
        "transitions": len(demos),
        "episodes_succeeded": demos.successes,
        "bc_action_mse": mse,
        "ignored_inputs": ignored,
    }
    (out / "demonstrations.json").write_text(json.dumps(record, indent=2) + "\n")
    return record
