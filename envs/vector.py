"""Many pouring envs in one process: a Gymnasium vector env whose envs step in threads.

``gym.make_vec("PourGym/Pour-v1", num_envs=8)`` makes one (every id registers it as its
``vector_entry_point``; ``vectorization_mode="vector_entry_point"`` asks for it by name).
Each env is the single env ``gym.make`` gives, with its fluid on one thread; a vector step
steps the envs in a pool of threads, one per core by default. The fluid's one-thread
kernel releases Python's lock while it runs, so while one env's fluid advances another
env's Python work (the action, the census, the features, the reward) goes on: the threads
keep every core busy with no worker processes, and with more envs than threads no env
waits for the slowest (a thread that finishes takes the next env). Each env's particles
are, bit for bit, what the single env with the same seed and actions gives.

One process holds every env: the envs share one
:class:`~pour_gym.envs.containers.ContainerStore` (a container's mesh and field are loaded
once, not once per env), and each extra env costs its fluid's and its world's memory only.
Semantics are Gymnasium 1.x's (:class:`gymnasium.vector.SyncVectorEnv`'s): batched spaces,
``autoreset_mode`` (next-step by default, same-step, or disabled), per-env seeds from
``reset(seed=...)``, infos as dicts of arrays with ``_key`` masks, ``final_obs`` and
``final_info`` under same-step autoreset, ``reset(options={"reset_mask": ...})``.
"""

from __future__ import annotations

import copy
import functools
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, create_empty_array, iterate

from pour_gym.envs.containers import KEPT, ContainerStore
from pour_gym.envs.registry import ENVS, vector_creator_name
from pour_gym.errors import InputError
from pour_gym.io.numba_threads import usable_cores


def autoreset(mode: str | AutoresetMode) -> AutoresetMode:
    """An :class:`~gymnasium.vector.AutoresetMode` from itself, its value or its name.

    Raises:
        ValueError: none of them; the message lists the modes.
    """
    if isinstance(mode, AutoresetMode):
        return mode
    words = str(mode).replace("-", "").replace("_", "").lower()
    for m in AutoresetMode:
        if words in (m.value.lower(), m.name.replace("_", "").lower()):
            return m
    names = ", ".join(m.value for m in AutoresetMode)
    raise InputError(f"autoreset_mode must be one of {names} (or next-step, ...), not {mode!r}")


# One env's result of a vector step: observation, reward, terminated, truncated, info, and
# (under same-step autoreset, for an env that ended) the observation and info it ended with.
Result = tuple[Any, float, bool, bool, dict, tuple[Any, dict] | None]


class PourVectorEnv(VectorEnv):
    """``num_envs`` pour-gym envs of one id stepped by a pool of threads in this process.

    Args:
        env_id: the id of the envs (``PourGym/Pour-v1``, say).
        num_envs: how many.
        num_threads: threads stepping the envs (default: the cores this process may use,
            at most ``num_envs``). Each env's own fluid runs on one thread.
        autoreset_mode: Gymnasium's :class:`~gymnasium.vector.AutoresetMode` or its
            value (``"NextStep"``, the default, ``"SameStep"``, ``"Disabled"``; also
            ``"next-step"``, ``"same-step"``, ``"disabled"``).
        copy: return copies of the batched observations (else the buffer, overwritten
            by the next call).
        max_episode_steps: the envs' time limit (default: the id's).
        wrappers: applied to each env in turn (SB3's ``Monitor``, a curriculum).
        **kwargs: every env's arguments, as for ``gym.make(env_id, ...)``.

    Raises:
        ValueError: ``num_envs`` or ``num_threads`` below 1, or an unknown autoreset mode.
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        num_threads: int | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        copy: bool = True,
        max_episode_steps: int | None = None,
        wrappers: Sequence[Callable[[gym.Env], gym.Env]] = (),
        **kwargs,
    ):
        if int(num_envs) < 1:
            raise InputError(f"num_envs must be at least 1, not {num_envs}")
        if num_threads is not None and int(num_threads) < 1:
            raise InputError(f"num_threads must be at least 1 (or None), not {num_threads}")
        super().__init__()
        self.env_id = env_id
        self.num_envs = int(num_envs)
        self.autoreset_mode = autoreset(autoreset_mode)
        self.copy = copy
        threads = usable_cores() if num_threads is None else int(num_threads)
        self.num_threads = max(1, min(threads, self.num_envs))
        # Two containers an episode in each env, and what a single env keeps besides.
        self.containers = ContainerStore(KEPT + 2 * self.num_envs)
        self.envs: list[gym.Env] = []
        try:
            for _ in range(self.num_envs):
                env = gym.make(
                    env_id,
                    max_episode_steps=max_episode_steps,
                    disable_env_checker=True,
                    **{**kwargs, "num_threads": 1},
                )
                env.unwrapped.share_containers(self.containers)
                for wrapper in wrappers:
                    env = wrapper(env)
                self.envs.append(env)
        except BaseException:
            for env in self.envs:
                env.close()
            raise
        first = self.envs[0]
        self.metadata = {**first.metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = first.render_mode
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._observations = create_empty_array(
            self.single_observation_space, n=self.num_envs, fn=np.zeros
        )
        self._ended = np.zeros(self.num_envs, dtype=bool)  # ended at the last step
        self._seconds = np.zeros(self.num_envs)  # each env's last step, s (for the order)
        self._pool = ThreadPoolExecutor(self.num_threads, thread_name_prefix="pour-gym env")

    # ------------------------------------------------------------------ episodes
    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict | None = None
    ) -> tuple[Any, dict]:
        """Reset the envs (those of ``options["reset_mask"]`` only, if given).

        Args:
            seed: ``None``, an int (env ``i`` takes ``seed + i``) or one seed per env.
            options: every env's reset options; ``reset_mask`` (a bool array of
                ``num_envs``) picks the envs to reset.
        """
        self._check_open()
        if seed is None or isinstance(seed, int | np.integer):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise InputError(
                    f"give one seed per env ({self.num_envs}), not {len(seeds)}: {seeds}"
                )
        n = self.num_envs
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(self.num_envs, dtype=bool)
        elif not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_) or len(mask) != n:
            raise InputError(f"options['reset_mask'] is a bool array of shape ({self.num_envs},)")
        chosen = [i for i in range(n) if mask[i]]
        done = self.reset_envs(chosen, [seeds[i] for i in chosen], [options] * len(chosen))
        infos: dict = {}
        for i, (_, info) in zip(chosen, done, strict=True):
            infos = self._add_info(infos, info, i)
        return self.observations(), infos

    def reset_envs(self, indices, seeds, options) -> list[tuple[Any, dict]]:
        """Reset some envs, each with its own seed and options; their results in order.

        Args:
            indices: which envs.
            seeds: a seed (or None) per env reset.
            options: reset options (a dict or None) per env reset.
        """
        indices = list(indices)
        done = self._map(
            lambda k: self.envs[indices[k]].reset(seed=seeds[k], options=options[k]),
            range(len(indices)),
        )
        for i, (obs, _) in zip(indices, done, strict=True):
            self._set_obs(i, obs)
            self._ended[i] = False
        return done

    def step(self, actions) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Step every env with its action (an env that ended resets, as the mode says)."""
        results = self.step_envs(actions)
        rewards = np.array([r[1] for r in results], dtype=np.float64)
        terminated = np.array([r[2] for r in results], dtype=bool)
        truncated = np.array([r[3] for r in results], dtype=bool)
        infos: dict = {}
        for i, (_, _, _, _, info, final) in enumerate(results):
            if final is not None:
                infos = self._add_info(infos, {"final_obs": final[0], "final_info": final[1]}, i)
            infos = self._add_info(infos, info, i)
        return self.observations(), rewards, terminated, truncated, infos

    def step_envs(self, actions) -> list[Result]:
        """Step every env; each env's own result, in order (the SB3 adapter reads these).

        The batched observations (:meth:`observations`) are updated too.

        Under next-step autoreset an env that ended at the last step resets instead
        (reward 0, its action ignored); under same-step an env that ends resets at once
        and its result carries the observation and info it ended with.
        """
        self._check_open()
        acts = list(iterate(self.action_space, actions))
        if len(acts) != self.num_envs:
            raise InputError(f"give one action per env ({self.num_envs}), not {len(acts)}")
        if self.autoreset_mode == AutoresetMode.DISABLED and self._ended.any():
            ended = np.flatnonzero(self._ended).tolist()
            raise RuntimeError(
                f"envs {ended} ended and autoreset_mode is disabled: reset them first "
                "(reset(options={'reset_mask': mask}))"
            )
        results = self._map(lambda i: self._step_one(i, acts[i]), range(self.num_envs))
        for i, result in enumerate(results):
            self._set_obs(i, result[0])
        self._ended = np.array([r[2] or r[3] for r in results], dtype=bool)
        return results

    def _step_one(self, i: int, action) -> Result:
        start = time.perf_counter()
        try:
            return self._advance_one(i, action)
        finally:
            self._seconds[i] = time.perf_counter() - start

    def _advance_one(self, i: int, action) -> Result:
        env = self.envs[i]
        if self.autoreset_mode == AutoresetMode.NEXT_STEP and self._ended[i]:
            obs, info = env.reset()
            return obs, 0.0, False, False, info, None
        obs, reward, terminated, truncated, info = env.step(action)
        final = None
        if self.autoreset_mode == AutoresetMode.SAME_STEP and (terminated or truncated):
            final = (obs, info)
            obs, info = env.reset()
        return obs, float(reward), bool(terminated), bool(truncated), info, final

    def _map(self, work, indices) -> list:
        """``work(i)`` for each index, in the pool; the results in the order of ``indices``.

        The envs whose last step took longest start first (longest processing time first):
        a vector step ends when its last env does, and a long step taken last would leave
        the other threads idle meanwhile. An exception in an env is raised here.
        """
        indices = list(indices)
        if self.num_threads == 1 or len(indices) == 1:
            return [work(i) for i in indices]
        first = sorted(indices, key=lambda i: -self._seconds[i])
        futures = {i: self._pool.submit(work, i) for i in first}
        return [futures[i].result() for i in indices]

    # ------------------------------------------------------------------ observations
    def _set_obs(self, i: int, obs) -> None:
        if isinstance(self._observations, dict):
            for key, value in obs.items():
                self._observations[key][i] = value
        else:
            self._observations[i] = obs

    def observations(self):
        """The envs' last observations, batched (a copy unless ``copy`` is false)."""
        return copy.deepcopy(self._observations) if self.copy else self._observations

    # ------------------------------------------------------------------ the rest of the API
    def render(self):
        """Env 0's picture (its ``render_mode``)."""
        self._check_open()
        return self.envs[0].render()

    def call(self, name: str, *args, **kwargs) -> tuple:
        """Call a method (or read an attribute) of every env; the results in order."""
        results = []
        for env in self.envs:
            value = env.get_wrapper_attr(name)
            results.append(value(*args, **kwargs) if callable(value) else value)
        return tuple(results)

    def get_attr(self, name: str) -> tuple:
        """An attribute of every env."""
        return tuple(env.get_wrapper_attr(name) for env in self.envs)

    def set_attr(self, name: str, values) -> None:
        """Set an attribute of every env (one value for all, or a list of one per env)."""
        if not isinstance(values, list | tuple):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise InputError(f"give one value per env ({self.num_envs}), not {len(values)}")
        for env, value in zip(self.envs, values, strict=True):
            env.set_wrapper_attr(name, value)

    def close_extras(self, **kwargs) -> None:
        """Close every env and the threads."""
        self._pool.shutdown(wait=True)
        for env in self.envs:
            env.close()
        self.containers.clear()

    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError(f"this {type(self).__name__} was closed; make a new one to go on")

    def __repr__(self) -> str:
        return f"PourVectorEnv({self.env_id}, num_envs={self.num_envs}, threads={self.num_threads})"


def __getattr__(name: str):
    """``vector_<slug>``: :class:`PourVectorEnv` of that id (what ``make_vec`` calls)."""
    for e in ENVS:
        if vector_creator_name(e.id) == name:
            return functools.partial(PourVectorEnv, e.id)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
