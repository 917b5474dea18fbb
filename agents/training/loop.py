"""``train``: make the vector env, build or resume the algorithm, learn, save, evaluate."""

from __future__ import annotations

import dataclasses
import json
import shutil
import time

from pour_gym.agents.evaluation.evaluate import evaluate_policy, evaluation_table, samples
from pour_gym.agents.policies.rollout import sb3_policy
from pour_gym.agents.training.config import TrainConfig, algorithm
from pour_gym.agents.training.curves import (
    keep_best_of_curve,
    plot_curve,
    record_curve_from_checkpoints,
    training_callbacks,
)
from pour_gym.agents.training.moved_modules import importable_old_paths
from pour_gym.agents.training.noise import noise_callback
from pour_gym.agents.training.recipes import Recipe, algorithm_arguments, load_recipe
from pour_gym.agents.training.runs import (
    BEST,
    NORMALISER,
    checkpoint_file,
    latest_checkpoint,
    load_run,
    save_normaliser,
)
from pour_gym.agents.training.schedule import (
    StepSchedule,
    SwitchState,
    schedule_callback,
    switch_callback,
)
from pour_gym.agents.training.vector import training_vec_env
from pour_gym.agents.training.warm_start import start_from_demonstrations
from pour_gym.assets import expand_containers
from pour_gym.envs import ENV_IDS, entry, task_of
from pour_gym.errors import InputError
from pour_gym.io.numba_threads import usable_cores


def env_arguments(config: TrainConfig, recipe: Recipe) -> dict:
    """A run's environment arguments, all but its containers.

    The observation mode, then the recipe's ``env_kwargs``, then the run's own (which
    win). Training, the learning curve, the evaluation and ``config.json`` all use these.
    """
    return {"obs_mode": config.obs_mode, **recipe.env_kwargs, **config.env_kwargs}


def make_training_env(config: TrainConfig, recipe: Recipe, env_kwargs: dict):
    """The vector env (``config.vec``), wrapped and normalised as the recipe says.

    A worker process of ``--vec subproc`` makes its env through
    :func:`pour_gym.envs.make`, which registers the ids in the worker's own process (a
    worker started from a Ray trial has not imported pour-gym).
    """
    from stable_baselines3.common.vec_env import VecNormalize

    venv = training_vec_env(
        config.env, recipe.n_envs, config.seed, env_kwargs, recipe.wrapper(), config.vec
    )
    if recipe.normalize:
        venv = VecNormalize(venv, **recipe.normalize)
    return venv


def train(config: TrainConfig) -> dict:
    """Train (or resume) an SB3 agent, save it, and evaluate it on every container.

    Returns:
        The evaluation document (also written to ``eval.json``), with ``model``,
        ``timesteps``, ``train_seconds`` (the wall time of everything before the
        evaluation in this process, s) and ``resumed_from`` (the steps of the checkpoint
        it resumed from; 0 for a run from scratch, whose earlier parts' SB3 logs are kept
        as ``progress_until_<steps>.csv``); with ``--keep-best``, ``best_point`` (the
        learning-curve point whose model was evaluated; run again with ``--keep-best``,
        a finished run picks it among its checkpoints).

    Raises:
        InputError: a bad option or recipe (named), before any work.
    """
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import VecNormalize

    started = time.perf_counter()
    cls = algorithm(config.algo)
    if config.timesteps <= 0:
        raise InputError(f"--timesteps must be positive, not {config.timesteps}")
    if config.keep_best and config.curve_every <= 0:
        raise InputError("--keep-best picks among learning-curve points: add --curve-every N")
    try:
        entry(config.env)
    except ValueError:
        raise InputError(
            f"unknown environment {config.env!r}; use one of {', '.join(ENV_IDS)}"
        ) from None
    recipe = load_recipe(config.env, config.algo, cls, config.overrides, config.recipe)
    if config.n_envs:
        if config.n_envs < 0:
            raise InputError(f"--n-envs must be positive (0: the recipe's), not {config.n_envs}")
        recipe = dataclasses.replace(recipe, n_envs=config.n_envs)
    if recipe.stochastic_eval:  # the recipe's way to score its policy; recorded as the run's
        config = dataclasses.replace(config, stochastic_eval=True)
    params = dict(recipe.hyperparameters)
    demos_cfg = recipe.demonstrations
    if demos_cfg:
        if config.algo not in ("sac", "tqc", "bc"):
            raise InputError(f"demonstrations need sac, tqc or bc, not {config.algo}")
        from pour_gym.agents.training.demonstrations import DemoReplayBuffer

        params["replay_buffer_class"] = DemoReplayBuffer
        params["replay_buffer_kwargs"] = {"demo_share": demos_cfg.share}
    train_objects = list(expand_containers(config.objects))
    eval_objects = list(expand_containers(config.eval_objects))  # a bad name fails before work
    arguments = env_arguments(config, recipe)
    out = config.run_dir()
    ckpt_dir = out / "checkpoints"
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    record = {
        **dataclasses.asdict(config),
        # The run's folder by name only: the record travels with the folder, and a shipped
        # model's config must not carry the training machine's paths.
        "out": out.name,
        "hyperparameters": {k: v for k, v in params.items() if k != "replay_buffer_class"},
        "demonstrations": dataclasses.asdict(demos_cfg) if demos_cfg else None,
        "n_envs": recipe.n_envs,
        "policy": recipe.policy,
        "normalize": recipe.normalize,
        "env_wrapper": recipe.env_wrapper,
        # A learner of corrections to the expert: whatever loads the run acts with both.
        "residual": recipe.residual.to_dict() if recipe.residual else None,
        "noise_schedule": (
            dataclasses.asdict(recipe.noise_schedule) if recipe.noise_schedule else None
        ),
        "env_schedule": StepSchedule.all_to_dict(recipe.env_schedule),
        "algo_schedule": StepSchedule.all_to_dict(recipe.algo_schedule),
        "switch": recipe.switch.to_dict() if recipe.switch else None,
        # What the environments were made with (recipe and run): evaluate uses it.
        "env_kwargs": arguments,
    }
    (out / "config.json").write_text(json.dumps(record, indent=2))
    import torch

    # The learner and the environments' fluid share the cores: one thread for torch.
    torch.set_num_threads(recipe.torch_threads)
    env_kwargs = {"objects": train_objects, **arguments}
    venv = make_training_env(config, recipe, env_kwargs)
    checkpoint, done = latest_checkpoint(ckpt_dir)
    if checkpoint is None:
        # A fresh run owns its curves: a folder trained into before (a shipped model's, say)
        # must not lend it old points.
        for stale in ("curve.csv", "bc_curve.csv", f"{BEST}/point.json", SwitchState.FILE):
            (out / stale).unlink(missing_ok=True)
        model = cls(recipe.policy, venv, seed=config.seed, verbose=0, device="cpu",
                    **algorithm_arguments(params))  # fmt: skip
        if demos_cfg:
            start_from_demonstrations(
                config, model, venv, env_kwargs, demos_cfg, recipe.wrapper(), out
            )
    else:
        stats = checkpoint_file(ckpt_dir, done, "normaliser")
        if recipe.normalize and stats.is_file():
            venv = VecNormalize.load(str(stats), venv.venv)
        importable_old_paths()  # a checkpoint saved before the agents were grouped
        # The recipe as this command gives it (its --set overrides included), not as the
        # checkpoint saved it: a run resumed with a new learning rate trains with it.
        try:
            model = cls.load(checkpoint, env=venv, seed=config.seed, device="cpu",
                             **algorithm_arguments(params))  # fmt: skip
        except ValueError as err:
            if "policy kwargs" not in str(err):
                raise
            raise InputError(
                f"{checkpoint} was saved with other policy_kwargs than the recipe gives: a "
                "network's shape cannot change when a run resumes (keep the recipe's "
                "policy_kwargs, or train into a new --out)"
            ) from err
        buffer = checkpoint_file(ckpt_dir, done, "replay_buffer")
        if buffer.is_file() and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(buffer)
        demos = getattr(getattr(model, "replay_buffer", None), "demonstrations", None)
        if demos_cfg and demos_cfg.bc_weight > 0 and demos is not None:
            # The behaviour-cloning term lives in the actor's optimiser, not in the save.
            from pour_gym.agents.training.demonstrations import regularise_actor

            normaliser = venv if isinstance(venv, VecNormalize) else None
            regularise_actor(model, demos, normaliser, weight=demos_cfg.bc_weight)
    if checkpoint is not None and (out / "progress.csv").is_file():
        # SB3's logger starts progress.csv afresh: the part before this resume is kept.
        (out / "progress.csv").replace(out / f"progress_until_{done}.csv")
    model.set_logger(configure(str(out), ["csv"]))
    remaining = config.timesteps - done
    if remaining > 0:
        callbacks = training_callbacks(config, out, config.timesteps, done, recipe.n_envs,
                                       env_kwargs)  # fmt: skip
        if recipe.noise_schedule is not None:
            callbacks.callbacks.append(noise_callback(recipe.noise_schedule, config.timesteps))
        # Where a resumed run's switch fired (none for a fresh run: removed above).
        switched = SwitchState.load(out) if recipe.switch else None
        if recipe.switch is not None:
            # Before the schedules': they read where it fired at the same rollout's start.
            callbacks.callbacks.append(switch_callback(recipe.switch, switched, out))
        for schedule in recipe.env_schedule + recipe.algo_schedule:
            callbacks.callbacks.append(schedule_callback(schedule, switched))
        model.learn(remaining, callback=callbacks, reset_num_timesteps=checkpoint is None)
        # The finished run is a checkpoint too: running the command again only evaluates.
        model.save(checkpoint_file(ckpt_dir, model.num_timesteps))
        save_normaliser(venv, ckpt_dir, model.num_timesteps)
    model.save(out / "model.zip")
    save_normaliser(venv, out)
    venv.close()
    if config.recurve:
        record_curve_from_checkpoints(config, out, env_kwargs)
    # Demonstrations, cloning, learning and the curve's episodes; not the evaluation below.
    # A resumed run counts this process's part only.
    train_seconds = time.perf_counter() - started
    best = out / BEST
    kept = keep_best_of_curve(out, task_of(config.env)) if config.keep_best else None
    if kept is not None:
        # The model is the best learning-curve point's (best/point.json says which).
        for name in ("model.zip", NORMALISER):
            if (best / name).is_file():
                shutil.copyfile(best / name, out / name)
    scored = "sampled actions" if config.stochastic_eval else "mean action"
    plot_curve(out, f"{config.env}, {config.algo}, {config.obs_mode}, {config.objects} ({scored})")
    run = load_run(out / "model.zip")
    policy = sb3_policy(run)
    result = evaluate_policy(
        policy,
        config.env,
        eval_objects,
        config.eval_episodes,
        seed=config.eval_seed,
        env_kwargs=arguments,
        trained_on=train_objects,
        # The training is over: its cores evaluate the containers at once (the same result).
        workers=1 if samples(policy) else usable_cores(),
    )
    result.update(model=str(out / "model.zip"), timesteps=config.timesteps, algo=config.algo,
                  train_seconds=train_seconds, resumed_from=done, best_point=kept)  # fmt: skip
    (out / "eval.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "eval.md").write_text(evaluation_table(result) + "\n")
    return result
