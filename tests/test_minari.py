"""The scripted expert's Minari dataset: it loads, and replays through the env bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from pour_gym.apps.cli import main
from pour_gym.envs import POUR_V1, entry

minari = pytest.importorskip("minari")


def test_dataset_loads_and_replays(tmp_path, monkeypatch):
    """``minari.load_dataset`` gives every step; a replay from the stored seed matches it."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    from pour_gym.agents.training.minari_dataset import record_minari_dataset

    kwargs = {**entry(POUR_V1).quick, "objects": ["red_cup"], "num_threads": 1}
    record_minari_dataset("pourgym/test-expert-v0", POUR_V1, kwargs, 2, seed=3, noise=0.05,
                          progress=False)  # fmt: skip
    dataset = minari.load_dataset("pourgym/test-expert-v0")
    assert dataset.total_episodes == 2
    env = dataset.recover_environment()
    seeds = [m["seed"] for m in dataset.storage.get_episode_metadata([0, 1])]
    assert seeds == [3, 4]
    for episode, seed in zip(dataset.iterate_episodes(), seeds, strict=True):
        n = len(episode.actions)
        assert episode.observations.shape == (n + 1, 16)
        assert episode.terminations[-1] or episode.truncations[-1]
        obs, _ = env.reset(seed=seed)
        np.testing.assert_array_equal(obs, episode.observations[0])
        total = 0.0
        for k, action in enumerate(episode.actions):
            obs, reward, terminated, truncated, _ = env.step(action)
            np.testing.assert_array_equal(obs, episode.observations[k + 1])
            assert reward == pytest.approx(episode.rewards[k], abs=0)
            assert terminated == episode.terminations[k] and truncated == episode.truncations[k]
            total += reward
        # The expert pours: a return above the progress term alone means it succeeded at times.
        assert total > 0.5
    env.close()


def test_command_refuses_bad_names_and_existing_datasets(tmp_path, capsys):
    """A malformed id, and an id that exists, end with a message and status 2."""
    args = ["demonstrations", "--objects", "red_cup", "--episodes", "1", "--out", str(tmp_path)]
    assert main([*args, "--minari", "no version"]) == 2
    assert "not a Minari dataset id" in capsys.readouterr().err
    (tmp_path / "pourgym" / "taken-v0").mkdir(parents=True)
    (tmp_path / "pourgym" / "taken-v0" / "metadata.json").write_text("{}")
    code = main([*args, "--minari", "pourgym/taken-v0"])
    assert code == 2, capsys.readouterr()
