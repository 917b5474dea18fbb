"""Augmented Random Search with every candidate scored on the same episodes.

sb3-contrib's ``ARS`` (Mania, Guy and Recht 2018, "Simple random search of static linear
policies is competitive for reinforcement learning") perturbs the policy's weights by
``n_delta`` random directions, scores each ``weights + delta`` and ``weights - delta`` by
its episodes' return, and steps along the directions whose two sides differ most. It
scores each candidate on whatever episodes the vector env serves next. Over a family of
containers that difference is mostly the episodes': one candidate pours from a wide bowl
into a tall glass, its mirror image between two cups, and the pair's return gap says
more about the containers and the target amounts than about the direction.

:class:`PairedARS` scores every candidate of an update on the same episodes (common
random numbers, as the thesis's policy search and :mod:`pour_gym.agents.policies.search`
do): the vector env's ``num_envs`` envs are reset from the same seeds for each candidate,
and each env's first episode counts. The observation statistics (``VecNormalize``) are
held while the candidates act, so every candidate sees its observations scaled alike,
and take in the update's observations afterwards (ARS's "V2" normalisation).
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch as th
from sb3_contrib import ARS
from stable_baselines3.common.callbacks import BaseCallback

from pour_gym.errors import InputError

# The updates' episode seeds start here: far above the seeds an evaluation takes
# (train.py's --eval-seed, the docs' 10000+ and 60000+), so training never meets them.
SEED_BASE = 1_000_000
SEED_SPAN = 2**31 - 1 - SEED_BASE


def update_seed(seed: int | None, update: int) -> int:
    """The first episode seed of an update (env ``i`` resets from it plus ``i``).

    A function of the run's seed and the update's index alone, so a resumed run scores
    its updates on the episodes the uninterrupted run would have.
    """
    state = np.random.SeedSequence([0 if seed is None else int(seed), int(update)])
    return SEED_BASE + int(state.generate_state(1)[0]) % SEED_SPAN


class PairedARS(ARS):
    """sb3-contrib's ARS with the candidates of an update scored on the same episodes.

    Each candidate acts in all ``num_envs`` envs of the vector env at once, reset from the
    update's seeds (:func:`update_seed`); its score is the summed return of each env's
    first episode. ``n_eval_episodes`` is not used: the number of envs is the number of
    episodes a candidate is scored on. A step of an env whose episode has ended (it
    waits for the others) counts in ``num_timesteps``, as the samples it cost.

    Raises:
        InputError: ``async_eval`` given to :meth:`learn` (the episodes would not be
            shared).
    """

    def evaluate_candidates(
        self, candidate_weights: th.Tensor, callback: BaseCallback, async_eval: Any
    ) -> th.Tensor:
        """Every candidate's summed return over the update's episodes."""
        if async_eval is not None:
            raise InputError(
                "PairedARS scores its candidates in one vector env: train without async_eval"
            )
        venv = self.env
        normaliser = self._vec_normalize_env
        first_seed = update_seed(self.seed, self._n_updates)
        # The candidates act through a copy: a checkpoint or a curve point taken between two
        # of their steps saves and scores the update's own weights.
        policy = copy.deepcopy(self.policy)
        returns = th.zeros(self.pop_size, device=self.device)
        seen: list[np.ndarray] = []
        successes: list[bool] = []
        self.ep_info_buffer = []
        callback.on_rollout_start()
        training = normaliser.training if normaliser is not None else False
        if normaliser is not None:
            normaliser.training = False
        try:
            for index in range(self.pop_size):
                policy.load_from_vector(candidate_weights[index].cpu())
                total, lengths, raw, won = self._episodes(venv, policy, first_seed, callback)
                returns[index] = float(total.sum()) + self.alive_bonus_offset * lengths.sum()
                self._mimic_monitor_wrapper(total, lengths)
                seen.extend(raw)
                successes.extend(won)
        finally:
            if normaliser is not None:
                normaliser.training = training
        if normaliser is not None and training and seen:
            normaliser.obs_rms.update(np.concatenate(seen))
        # The candidates' episodes that succeeded (the update's weights are not scored).
        self.logger.record("rollout/success_rate", float(np.mean(successes)))
        callback.on_rollout_end()
        return returns

    def _episodes(
        self, venv, policy, first_seed: int, callback: BaseCallback
    ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray], list[bool]]:
        """Each env's first episode from its seed.

        Returns:
            The episodes' returns and lengths (steps), the raw observations the policy
            acted on, and whether each episode succeeded (``info["is_success"]``).
        """
        n = venv.num_envs
        venv.seed(first_seed)
        obs = venv.reset()
        normaliser = self._vec_normalize_env
        raw = [normaliser.get_original_obs()] if normaliser is not None else []
        active = np.ones(n, dtype=bool)
        total = np.zeros(n)
        lengths = np.zeros(n, dtype=np.int64)
        won = [False] * n
        while active.any():
            actions, _ = policy.predict(obs, deterministic=True)
            obs, rewards, dones, infos = venv.step(actions)
            total[active] += rewards[active]
            lengths[active] += 1
            for i in np.flatnonzero(active & dones):
                won[i] = bool(infos[i].get("is_success", False))
            if normaliser is not None:
                # The observations the candidate acted on; an ended env's next one is a
                # new episode's, which no candidate is scored on.
                raw.append(normaliser.get_original_obs()[active & ~dones])
            active &= ~dones
            self.num_timesteps += n
            callback.update_locals(locals())
            if not callback.on_step():
                break
        return total, lengths, raw, won
