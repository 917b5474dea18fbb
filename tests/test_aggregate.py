"""rliable's aggregates as pour-gym computes them, against rliable's own definitions."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import mannwhitneyu, trim_mean

from pour_gym.agents.evaluation.aggregate import (
    bootstrap_interval,
    iqm,
    mean_score,
    normalised,
    probability_of_improvement,
)
from pour_gym.agents.evaluation.baselines import baselines_report


def _rliable_improvement(x: np.ndarray, y: np.ndarray) -> float:
    """rliable.metrics.probability_of_improvement, as rliable writes it."""
    probabilities = []
    for task in range(x.shape[1]):
        if np.array_equal(x[:, task], y[:, task]):
            probabilities.append(0.5)
            continue
        u, _ = mannwhitneyu(x[:, task], y[:, task], alternative="greater")
        probabilities.append(u / (x.shape[0] * y.shape[0]))
    return float(np.mean(probabilities))


def test_the_aggregates_are_rliables():
    rng = np.random.default_rng(0)
    for runs, tasks in ((3, 11), (5, 4), (10, 1)):
        x = np.round(rng.normal(size=(runs, tasks)), 1)  # rounded: ties happen
        y = np.round(rng.normal(size=(4, tasks)), 1)
        assert iqm(x) == pytest.approx(trim_mean(x, 0.25, axis=None), abs=1e-12)
        assert probability_of_improvement(x, y) == pytest.approx(_rliable_improvement(x, y))
        assert probability_of_improvement(x, x) == pytest.approx(0.5)
    # Vectorised over replicates: a stack gives each matrix's value.
    stack = rng.normal(size=(6, 3, 5))
    assert np.allclose(iqm(stack), [trim_mean(m, 0.25, axis=None) for m in stack])


def test_stratified_bootstrap_intervals():
    rng = np.random.default_rng(1)
    x = rng.normal(loc=2.0, size=(5, 8))
    low, high = bootstrap_interval(iqm, x, reps=4000)
    assert low < iqm(x) < high and high - low < 2.0
    assert bootstrap_interval(iqm, x, reps=4000) == (low, high)  # seeded
    # Resampled within each task: a task's scores never move to another task. With one
    # value per task repeated over the runs, every replicate is the matrix itself.
    same = np.tile(np.arange(6.0), (4, 1))
    assert bootstrap_interval(mean_score, same) == (2.5, 2.5)
    one = np.array([[0.3], [0.3]])
    assert bootstrap_interval(mean_score, one) == (0.3, 0.3)
    y = np.zeros((1, 8))
    lo, hi = bootstrap_interval(probability_of_improvement, x + 10, y)
    assert lo == hi == 1.0  # every run of every task above


def test_normalised_scores_put_random_at_0_and_the_expert_at_1():
    low, high = np.array([0.0, -1.0]), np.array([2.0, 1.0])
    assert np.allclose(normalised(np.array([[0.0, -1.0], [2.0, 1.0], [4.0, 0.0]]), low, high),
                       [[0, 0], [1, 1], [2, 0.5]])  # fmt: skip
    with pytest.raises(ValueError, match="score the same"):
        normalised(np.zeros((1, 2)), low, low)


def test_the_report_gives_each_row_its_aggregates_over_seeds_and_containers(tmp_path):
    def evaluation(path, returns, policy=None, trained=False):
        names = ("red_cup", "broad_cup", "high_cup")
        rows = [{"object": o, "trained_on": trained and o == "red_cup", "success": 1.0,
                 "return": r, "amount_error": 1.0, "spilled": 0.0}
                for o, r in zip(names, returns, strict=True)]  # fmt: skip
        doc = {"env": "PourGym/Pour-v1", "episodes": 10, "rows": rows}
        if policy:
            doc["policy"] = policy
        path.write_text(json.dumps(doc))

    for seed, returns in enumerate([(2.0, 1.0, 2.0), (2.0, 2.0, 3.0), (2.0, 1.5, 0.0)]):
        run = tmp_path / "runs" / f"ppo_s{seed}"
        run.mkdir(parents=True)
        (run / "config.json").write_text(json.dumps(
            {"env": "PourGym/Pour-v1", "algo": "ppo", "obs_mode": "features", "seed": seed,
             "timesteps": 1000, "objects": "red_cup"}))  # fmt: skip
        evaluation(run / "eval.json", returns, trained=True)
    evaluation(tmp_path / "random.json", (0.0, 0.0, 0.0), policy="random")
    evaluation(tmp_path / "expert.json", (2.0, 2.0, 2.0), policy="scripted")
    paths = {"summaries": tmp_path / "sum", "report": tmp_path / "b.md",
             "curves": tmp_path / "b" / "curves.png"}  # fmt: skip
    doc = baselines_report([tmp_path / "runs"], reference=[tmp_path / "random.json",
                           tmp_path / "expert.json"], **paths)  # fmt: skip
    rows = {r["algo"]: r for r in doc["rows"]}
    # Normalised on the unseen broad and high cups: seeds (0.5, 1), (1, 1.5), (0.75, 0).
    value, (low, high) = rows["ppo"]["iqm"]
    assert value == pytest.approx(trim_mean([0.5, 1, 1, 1.5, 0.75, 0], 0.25))
    assert low <= value <= high
    improvement, _ = rows["ppo"]["improvement"]
    # Against the expert's 1: broad (0 + 0.5 + 0) / 3, high (0.5 + 1 + 0) / 3.
    assert improvement == pytest.approx(np.mean([0.5 / 3, 1.5 / 3]))
    assert rows["scripted"]["iqm"][0] == 1.0 and rows["random"]["iqm"][0] == 0.0
    # One run: no seeds to resample, so no interval (not the value twice).
    assert rows["scripted"]["iqm"][1] is None and rows["random"]["improvement"][1] is None
    text = paths["report"].read_text()
    assert "| RANDOM | - | - | uniform random (reference) |" in text
    assert "normalised return, unseen (IQM)" in text
