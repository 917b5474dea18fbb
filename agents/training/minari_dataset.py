"""The scripted expert's episodes as a Minari dataset (Farama's offline-RL format).

``pour-gym demonstrations --minari NAME`` records the scripted policy
(:class:`~pour_gym.agents.training.demonstrations.NoisyExpert`, noise optional) in a Pour env
and writes its episodes with Minari, so that ``minari.load_dataset(NAME)`` gives its
observations, actions, rewards, terminations and truncations as any offline-RL library
reads them. Every episode's reset seed is stored by Minari (``episode.id`` k was reset
with ``seed + k``): replaying an episode's actions through the same env from that seed
gives its observations again, bit for bit (``tests/test_minari.py``).

Minari is an optional dependency: ``pip install 'pour-gym[data]'``.
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from pour_gym.agents.policies.rollout import Step, rollout
from pour_gym.agents.training.demonstrations import NoisyExpert, check_recording
from pour_gym.envs import make
from pour_gym.errors import InputError

ROOT_VARIABLE = "MINARI_DATASETS_PATH"


def _minari():
    try:
        import minari
    except ImportError:
        raise InputError(
            "Minari datasets need the minari and h5py packages: pip install 'pour-gym[data]'"
        ) from None
    return minari


@contextlib.contextmanager
def datasets_root(root: Path | None) -> Iterator[None]:
    """Minari's datasets folder set to ``root`` inside the block (its own when None).

    Minari reads the folder from ``MINARI_DATASETS_PATH`` whenever it opens a dataset; the
    variable is restored after the block.
    """
    if root is None:
        yield
        return
    before = os.environ.get(ROOT_VARIABLE)
    os.environ[ROOT_VARIABLE] = str(Path(root).resolve())
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ROOT_VARIABLE, None)
        else:
            os.environ[ROOT_VARIABLE] = before


def record_minari_dataset(
    name: str,
    env_id: str,
    env_kwargs: dict,
    episodes: int,
    seed: int = 0,
    noise: float | tuple[float, ...] = 0.0,
    expert: dict | None = None,
    wrapper: Callable[[gym.Env], gym.Env] | None = None,
    root: Path | None = None,
    progress: bool = True,
):
    """Record the scripted expert's episodes as the Minari dataset ``name``.

    Args:
        name: the dataset id, Minari's form ``[namespace/]name-vN`` (e.g.
            ``pourgym/red-cup-expert-v0``).
        env_id: a pouring env's id (``PourGym/Pour-v0`` or ``-v1``).
        env_kwargs: the env's arguments (containers, ``obs_mode``, ...).
        episodes: how many episodes.
        seed: the first episode's reset seed (episode k is reset with ``seed + k``).
        noise: standard deviation of Gaussian noise on the executed actions (one value or
            one per action), action units; 0 for the expert's own actions.
        expert: arguments of the :class:`~pour_gym.agents.policies.scripted.ScriptedPourPolicy`.
        wrapper: wraps the env before recording (a curriculum's starts), or None.
        root: the datasets folder (Minari's own, ``~/.minari/datasets`` or
            ``$MINARI_DATASETS_PATH``, when None).
        progress: show a progress bar.

    Returns:
        The ``minari.MinariDataset``.

    Raises:
        InputError: Minari missing, a malformed or existing name, a bad noise, an env
            the expert cannot pour in.
    """
    minari = _minari()
    from minari.dataset.minari_dataset import parse_dataset_id
    from minari.storage.datasets_root_dir import get_dataset_path

    try:
        parse_dataset_id(name)
    except Exception:
        raise InputError(
            f"{name!r} is not a Minari dataset id: use [namespace/]name-vN, e.g. "
            "pourgym/red-cup-expert-v0"
        ) from None
    sigma = check_recording(env_id, episodes, noise)
    with datasets_root(root):
        where = get_dataset_path(name)
        if where.exists():
            raise InputError(
                f"the Minari dataset {name} exists ({where}): delete it "
                f"(minari delete {name}) or record under another name"
            )
        env = make(env_id, **env_kwargs)
        if wrapper is not None:
            env = wrapper(env)
        try:
            policy = NoisyExpert(env.unwrapped, expert, sigma, np.random.default_rng(seed))
            buffers, successes = [], 0
            bar = tqdm(total=episodes, desc="dataset", file=sys.stderr, disable=not progress)
            for k in range(episodes):
                steps: list[Step] = []
                episode = rollout(env, policy, seed=seed + k, on_step=steps.append)
                successes += bool(episode.info["is_success"])
                buffers.append(_episode_buffer(k, seed + k, steps))
                bar.update(1)
                bar.set_postfix(success=f"{successes}/{k + 1}")
            bar.close()
            described = "no noise" if not sigma.any() else f"Gaussian noise {sigma.tolist()}"
            with warnings.catch_warnings():
                # Minari asks for a code permalink and an author e-mail, which a dataset
                # recorded on a user's machine does not have.
                warnings.simplefilter("ignore", UserWarning)
                dataset = minari.create_dataset_from_buffers(
                    dataset_id=name,
                    buffer=buffers,
                    env=env.spec,
                    eval_env=env.spec,
                    algorithm_name=f"pour-gym scripted expert (ScriptedPourPolicy, {described})",
                    author="pour-gym",
                    description=(
                        f"{episodes} episodes of pour-gym's scripted pouring policy in {env_id} "
                        f"({successes} succeeded); episode k was reset with seed {seed} + k; "
                        f"env arguments {env_kwargs}"
                        + (f"; starts drawn by {wrapper}" if wrapper is not None else "")
                    ),
                    requirements=["pour-gym"],
                    data_format="hdf5",
                )
        finally:
            env.close()
    return dataset


def _episode_buffer(index: int, seed: int, steps: list[Step]):
    """One episode's steps as Minari's ``EpisodeBuffer`` (observations: one more than steps).

    Built directly rather than through Minari's ``DataCollector``, which needs jax.
    """
    from minari.data_collector import EpisodeBuffer

    return EpisodeBuffer(
        id=index,
        seed=seed,
        observations=[steps[0].obs, *(s.next_obs for s in steps)],
        actions=[s.action for s in steps],
        rewards=[s.reward for s in steps],
        terminations=[s.terminated for s in steps],
        truncations=[s.truncated for s in steps],
        infos={},
    )
