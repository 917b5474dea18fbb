"""The environments a training run steps: pour-gym's native vector env as an SB3 ``VecEnv``.

``train.py --vec native`` (the default) trains on
:class:`~pour_gym.envs.vector.PourVectorEnv` (the envs in threads of one process) through
:class:`NativeVecEnv`; ``--vec subproc`` on SB3's ``SubprocVecEnv`` (a worker process per
env), ``--vec dummy`` on ``DummyVecEnv`` (one after the other). The three give the same
episodes for the same seeds and actions; the native one is the fastest on a multi-core
machine and holds the containers once (``pour-gym bench envs --sections native``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.env_util import is_wrapped, make_vec_env
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv

from pour_gym.envs import make
from pour_gym.envs.vector import PourVectorEnv
from pour_gym.errors import InputError

VECTORS = ("native", "subproc", "dummy")


class NativeVecEnv(VecEnv):
    """SB3's ``VecEnv`` over a :class:`~pour_gym.envs.vector.PourVectorEnv`.

    SB3's conventions: an env that ends resets at once, its last observation in
    ``info["terminal_observation"]`` and ``info["TimeLimit.truncated"]`` saying whether
    the time limit ended it; seeds and options from :meth:`seed` and :meth:`set_options`
    apply to the next :meth:`reset`.

    Args:
        env_id: the envs' id.
        num_envs: how many.
        env_kwargs: their arguments.
        wrappers: applied to each env (``Monitor`` first, for SB3's episode statistics).
        num_threads: threads stepping the envs (default: one per core).
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        env_kwargs: dict | None = None,
        wrappers: Sequence[Callable[[gym.Env], gym.Env]] = (Monitor,),
        num_threads: int | None = None,
    ):
        self.vector = PourVectorEnv(
            env_id,
            num_envs,
            num_threads=num_threads,
            autoreset_mode="same-step",
            wrappers=wrappers,
            **(env_kwargs or {}),
        )
        super().__init__(
            num_envs, self.vector.single_observation_space, self.vector.single_action_space
        )
        self.metadata = self.vector.metadata
        self.render_mode = self.vector.render_mode
        self._actions: np.ndarray | None = None

    def reset(self) -> Any:
        """Reset every env (with the seeds and options set for this reset)."""
        options = [opts or None for opts in self._options]
        done = self.vector.reset_envs(range(self.num_envs), list(self._seeds), options)
        self.reset_infos = [info for _, info in done]
        self._reset_seeds()
        self._reset_options()
        return self.vector.observations()

    def step_async(self, actions: np.ndarray) -> None:
        """Take the actions the next :meth:`step_wait` steps with."""
        self._actions = actions

    def step_wait(self):
        """Step every env: observations, rewards, dones and infos, as SB3 has them."""
        results = self.vector.step_envs(self._actions)
        # float64, as SubprocVecEnv's (DummyVecEnv's are float32): VecNormalize's return
        # statistics then match a SubprocVecEnv run's bit for bit.
        rewards = np.array([r[1] for r in results], dtype=np.float64)
        dones = np.array([r[2] or r[3] for r in results], dtype=bool)
        infos = []
        for i, (_, _, terminated, truncated, info, final) in enumerate(results):
            if final is not None:
                self.reset_infos[i] = info
                info = {**final[1], "terminal_observation": final[0]}
            infos.append({**info, "TimeLimit.truncated": truncated and not terminated})
        return self.vector.observations(), rewards, dones, infos

    def close(self) -> None:
        """Close every env."""
        self.vector.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Every env's picture."""
        return [env.render() for env in self.vector.envs]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """An attribute of the envs (all, or those of ``indices``)."""
        return [self.vector.envs[i].get_wrapper_attr(attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """Set an attribute of the envs (all, or those of ``indices``)."""
        for i in self._get_indices(indices):
            setattr(self.vector.envs[i], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        """Call a method of the envs (all, or those of ``indices``)."""
        return [
            self.vector.envs[i].get_wrapper_attr(method_name)(*method_args, **method_kwargs)
            for i in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices=None) -> list[bool]:
        """Whether the envs are wrapped in ``wrapper_class``."""
        return [is_wrapped(self.vector.envs[i], wrapper_class) for i in self._get_indices(indices)]


def training_vec_env(
    env_id: str,
    n_envs: int,
    seed: int,
    env_kwargs: dict,
    wrapper: Callable[[gym.Env], gym.Env] | None = None,
    vec: str = "native",
) -> VecEnv:
    """The vector env of a training run, seeded as SB3's ``make_vec_env`` seeds its envs.

    Args:
        env_id: the envs' id.
        n_envs: how many.
        seed: env ``i`` is reset first with ``seed + i``.
        env_kwargs: their arguments.
        wrapper: a wrapper around each env (outside SB3's ``Monitor``, where
            ``make_vec_env`` puts it).
        vec: ``"native"`` (:class:`NativeVecEnv`), ``"subproc"`` (a worker process per
            env, started with forkserver) or ``"dummy"`` (one after the other).

    Raises:
        InputError: an unknown ``vec``.
    """
    if vec not in VECTORS:
        raise InputError(f"unknown vector env {vec!r}; use one of {', '.join(VECTORS)}")
    if vec == "native":
        wrappers = [w for w in (Monitor, wrapper) if w is not None]
        venv = NativeVecEnv(env_id, n_envs, env_kwargs, wrappers)
        venv.seed(seed)
        for rank, env in enumerate(venv.vector.envs):
            env.action_space.seed(seed + rank)
        return venv
    vector: dict = {"vec_env_cls": DummyVecEnv}
    if vec == "subproc":
        vector = {"vec_env_cls": SubprocVecEnv, "vec_env_kwargs": {"start_method": "forkserver"}}
    return make_vec_env(
        functools.partial(make, env_id), n_envs=n_envs, seed=seed, env_kwargs=env_kwargs,
        wrapper_class=wrapper, **vector,
    )  # fmt: skip
