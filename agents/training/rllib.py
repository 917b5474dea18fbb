"""The pour-gym environments under Ray RLlib, as they are.

RLlib builds its environments inside env runners, Ray actors in processes of their own,
from a creator registered with ``ray.tune.register_env`` (Gymnasium's registry is not
what they look in). :func:`register` registers every ``PourGym/`` id that way; the
creator is ``gymnasium.make(id, **env_config)``, so an ``env_config`` holds the
environment's own arguments. Ray gives a worker of one CPU ``OMP_NUM_THREADS=1``, and the
fluid then runs on one thread (:func:`pour_gym.fluid.pbf.default_threads`): one env runner
per core is how it scales.

RLlib is an extra of its own (``pip install 'pour-gym[rllib]'``): ``ray[rllib]`` 2.60 pins
Gymnasium 1.2.2, and the rest of the suite runs on Gymnasium 1.4, so ``make test``
proves this path in a second virtual environment (``.venv-rllib``).

    python -m pour_gym.agents.training.rllib --env PourGym/TiltPour-v0 --env-runners 2 --json

trains PPO for one iteration and prints what it sampled.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import sys

from pour_gym.envs import TILT_POUR_V0
from pour_gym.errors import InputError

RLLIB_EXTRA = "pip install 'pour-gym[rllib]'"


def _make(env_id: str, env_config) -> object:
    """The env RLlib asks for: ``gymnasium.make(env_id, **env_config)``."""
    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments in this process

    return gym.make(env_id, **dict(env_config or {}))


def register(env_ids=None) -> list[str]:
    """Register pour-gym environments with RLlib (``ray.tune.register_env``).

    Args:
        env_ids: the ids (default: every ``PourGym/`` id).

    Returns:
        The registered ids; use them as ``PPOConfig().environment(env=id)``.

    Raises:
        InputError: Ray's RLlib is not installed.
    """
    try:
        from ray.tune.registry import register_env
    except ImportError:
        raise InputError(f"RLlib needs Ray with RLlib: {RLLIB_EXTRA}") from None
    from pour_gym.envs import ENV_IDS

    ids = list(env_ids or ENV_IDS)
    for env_id in ids:
        register_env(env_id, functools.partial(_make, env_id))
    return ids


def _runner_facts(runner) -> dict:
    """What an env runner's process is (for the check that runners are separate processes)."""
    from pour_gym.fluid.pbf import default_threads

    return {
        "pid": os.getpid(),
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        "fluid_threads": default_threads(),
    }


def ppo_iteration(
    env_id: str,
    env_runners: int = 2,
    env_config: dict | None = None,
    batch_size: int = 128,
    seed: int = 0,
    temp_dir: str | None = None,
) -> dict:
    """Train RLlib's PPO for one iteration on a pour-gym environment; what happened.

    Starts a local Ray instance that declares one logical CPU per env runner plus one for
    the driver and its learner (more than a 2-core machine has: the runners take turns on
    the cores).

    Args:
        env_id: a ``PourGym/`` id.
        env_runners: env runner actors (each in its own process).
        env_config: the environment's arguments.
        batch_size: environment steps of the iteration (the train batch).
        seed: RLlib's seed.
        temp_dir: Ray's session folder (Ray's default if None).

    Returns:
        ``{"env", "env_runners", "env_steps_sampled", "episodes", "runners": [{"pid",
        "omp_num_threads", "fluid_threads"}], "driver_pid", "gymnasium", "ray"}``.
    """
    try:
        import ray
        from ray.rllib.algorithms.ppo import PPOConfig
    except ImportError:
        raise InputError(f"RLlib needs Ray with RLlib: {RLLIB_EXTRA}") from None
    import gymnasium as gym

    register([env_id])
    ray.init(
        num_cpus=env_runners + 1,
        include_dashboard=False,
        log_to_driver=False,
        **({"_temp_dir": temp_dir} if temp_dir else {}),
    )
    try:
        config = (
            PPOConfig()
            .environment(env=env_id, env_config=dict(env_config or {}))
            .env_runners(
                num_env_runners=env_runners,
                num_cpus_per_env_runner=1,
                rollout_fragment_length="auto",
                # RLlib discards a runner's samples after 60 s by default: a fluid env
                # on a busy laptop (its first reset builds the containers' fields) can
                # take longer, and the iteration then trains on nothing.
                sample_timeout_s=600.0,
            )
            .training(
                train_batch_size_per_learner=batch_size,
                minibatch_size=min(64, batch_size),
                num_epochs=1,
            )
            .debugging(seed=seed)
        )
        algo = config.build_algo()
        result = algo.train()
        runners = algo.env_runner_group.foreach_env_runner(_runner_facts, local_env_runner=False)
        algo.stop()
    finally:
        ray.shutdown()
    runners_doc = result.get("env_runners", {})
    return {
        "env": env_id,
        "env_runners": env_runners,
        "env_steps_sampled": int(
            runners_doc.get("num_env_steps_sampled_lifetime", 0)
            or result.get("num_env_steps_sampled_lifetime", 0)
        ),
        "episodes": int(runners_doc.get("num_episodes_lifetime", 0)),
        "runners": list(runners),
        "driver_pid": os.getpid(),
        "gymnasium": gym.__version__,
        "ray": ray.__version__,
    }


def main(argv: list[str] | None = None) -> int:
    """``python -m pour_gym.agents.training.rllib``: one PPO iteration; exit 2 on bad input."""
    p = argparse.ArgumentParser(description="one RLlib PPO iteration on a pour-gym env")
    p.add_argument("--env", default=TILT_POUR_V0)
    p.add_argument("--env-runners", type=int, default=2)
    p.add_argument("--env-config", type=json.loads, default={}, help="JSON of env arguments")
    p.add_argument("--batch-size", type=int, default=128)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--ray-temp-dir", default=None, help="Ray's session folder")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    args = p.parse_args(argv)
    try:
        if args.env_runners < 1:
            raise InputError(f"--env-runners must be at least 1, not {args.env_runners}")
        doc = ppo_iteration(args.env, args.env_runners, args.env_config, args.batch_size,
                            args.seed, args.ray_temp_dir)  # fmt: skip
    except InputError as exc:
        print(f"pour_gym.agents.training.rllib: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(doc))
    else:
        print(
            f"{doc['env']}: PPO sampled {doc['env_steps_sampled']} steps "
            f"({doc['episodes']} episodes) on {doc['env_runners']} env runners "
            f"(pids {', '.join(str(r['pid']) for r in doc['runners'])}; fluid threads "
            f"{', '.join(str(r['fluid_threads']) for r in doc['runners'])}); "
            f"gymnasium {doc['gymnasium']}, ray {doc['ray']}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
