"""Scores over runs and tasks, as rliable defines them (Agarwal et al., NeurIPS 2021).

A score matrix is ``(runs, tasks)``: one row per seed, one column per task (here a container
a policy is evaluated on). rliable's definitions, written out here over NumPy so that the
baselines report needs none of its dependencies (arch, statsmodels, seaborn):

- the interquartile mean (IQM): the mean of the middle half of all runs' and tasks' scores
  (``scipy.stats.trim_mean(scores, 0.25, axis=None)``);
- the stratified bootstrap: a replicate draws, for every task, as many runs as there are,
  with replacement, from that task's runs (rliable's ``StratifiedBootstrap``); the
  interval is the replicates' 2.5th and 97.5th percentiles (its ``percentile`` method);
- the probability of improvement of X over Y: on each task, the chance that a run of X
  scores above a run of Y (ties count a half: the Mann-Whitney U over the runs' pairs),
  averaged over the tasks; its interval bootstraps X and Y independently, each stratified;
- a normalised score: ``(score - random) / (reference - random)`` per task, 0 for a
  seeded random policy and 1 for the reference on the same episodes (Minari's
  ``ref_min_score`` and ``ref_max_score``).

Every interval the project reports comes from here: :func:`bootstrap_interval` (and
:func:`mean_interval`, the mean over seeds) for statistics over runs, and
:func:`wilson_interval` for a success rate over episodes.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

CONFIDENCE = 0.95
REPLICATES = 20_000


def iqm(scores: np.ndarray) -> np.ndarray:
    """The interquartile mean of every score, over the last two axes (runs, tasks).

    Args:
        scores: ``(..., runs, tasks)``.

    Returns:
        One IQM per leading index (a float for a plain matrix).
    """
    x = np.asarray(scores, dtype=np.float64)
    flat = np.sort(x.reshape(*x.shape[:-2], -1), axis=-1)
    cut = int(0.25 * flat.shape[-1])  # scipy's trim_mean cuts int(proportion * n) each end
    return flat[..., cut : flat.shape[-1] - cut].mean(axis=-1)


def mean_score(scores: np.ndarray) -> np.ndarray:
    """The mean of every score, over the last two axes (runs, tasks)."""
    x = np.asarray(scores, dtype=np.float64)
    return x.reshape(*x.shape[:-2], -1).mean(axis=-1)


def probability_of_improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(a run of X beats a run of Y) per task (ties a half), averaged over the tasks.

    Args:
        x: ``(..., runs_x, tasks)``.
        y: ``(..., runs_y, tasks)``, the same tasks.
    """
    a = np.asarray(x, dtype=np.float64)[..., :, None, :]
    b = np.asarray(y, dtype=np.float64)[..., None, :, :]
    wins = (a > b) + 0.5 * (a == b)
    return wins.mean(axis=(-3, -2)).mean(axis=-1)


def _resample(scores: np.ndarray, rng: np.random.Generator, reps: int) -> np.ndarray:
    """``reps`` stratified replicates of a ``(runs, tasks)`` matrix: ``(reps, runs, tasks)``."""
    x = np.asarray(scores, dtype=np.float64)
    runs, tasks = x.shape
    picks = rng.integers(0, runs, size=(reps, runs, tasks))
    return x[picks, np.arange(tasks)]


def bootstrap_interval(
    statistic: Callable[..., np.ndarray],
    *samples: np.ndarray,
    reps: int = REPLICATES,
    seed: int = 0,
) -> tuple[float, float]:
    """The 95 % stratified-bootstrap percentile interval of a statistic of score matrices.

    Args:
        statistic: of one ``(reps, runs, tasks)`` stack per sample, vectorised over reps
            (:func:`iqm`, :func:`mean_score`, :func:`probability_of_improvement`).
        samples: ``(runs, tasks)`` matrices, each resampled on its own (stratified by task).
        reps: bootstrap replicates.
        seed: the resampling's seed (the same interval for the same scores).

    Returns:
        (low, high). A sample of one run per task gives the statistic itself twice.
    """
    rng = np.random.default_rng(seed)
    values = statistic(*(_resample(s, rng, reps) for s in samples))
    alpha = 100 * (1 - CONFIDENCE) / 2
    low, high = np.percentile(values, [alpha, 100 - alpha])
    return float(low), float(high)


def normalised(scores: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Scores as a share of the way from ``low`` (0) to ``high`` (1), per task.

    Args:
        scores: ``(runs, tasks)``.
        low: ``(tasks,)``, a seeded random policy's scores on the same episodes.
        high: ``(tasks,)``, the reference's (the scripted expert's).

    Raises:
        ValueError: a task on which the two references score the same (nothing to scale by).
    """
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    span = high - low
    if np.any(np.abs(span) < 1e-12):
        raise ValueError("the random policy and the reference score the same on a task")
    return (np.asarray(scores, dtype=np.float64) - low) / span


def mean_interval(values: list[float]) -> tuple[float, float] | None:
    """The 95 % bootstrap interval of the mean over seeds (None for one seed)."""
    if len(values) < 2:
        return None
    return bootstrap_interval(mean_score, np.asarray(values, dtype=np.float64)[:, None])


def wilson_interval(successes: float, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95 % for z = 1.96).

    Args:
        successes: successful episodes (a mean times n is fine).
        n: episodes.
        z: the normal quantile of the interval's confidence.
    """
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    # The interval holds p in exact arithmetic; rounding at p = 0 or 1 must not put it out.
    return (float(max(0.0, min(centre - half, p))), float(min(1.0, max(centre + half, p))))
