"""A small soak: random actions on a catalogue cup and on meshes made the way users' are
(a mug of two overlapping bodies with 5 mm walls, a cup with 3 mm walls)."""

import json

import pytest

from pour_gym.apps.soak import soak, user_meshes


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ["PourGym/Pour-v0", "PourGym/ParticleDrop-v0"])
def test_random_actions_break_nothing(env_id, tmp_path):
    objects = ["red_cup", *user_meshes(tmp_path)]
    kwargs = {"amount_range": (50, 100)} if env_id == "PourGym/Pour-v0" else {}
    doc = soak(env_id, objects, episodes=2, steps=60, seed=1, env_kwargs=kwargs)
    assert doc["episodes"] == 6
    for key in ("exceptions", "false_endings", "particles_lost", "wall_violations"):
        assert doc[key] == 0, (key, doc["errors"], doc["by_object"])


@pytest.mark.slow
def test_soak_command_prints_the_counts(tmp_path, cli):
    proc = cli("soak", "--env", "PourGym/TiltPour-v0", "--objects", "red_cup",
               "--episodes", "3", "--json")  # fmt: skip
    doc = json.loads(proc.stdout)
    assert {"episodes", "exceptions", "false_endings", "particles_lost", "wall_violations",
            "corrections", "steps_per_s"} <= set(doc)  # fmt: skip
    assert doc["episodes"] == 3 and doc["exceptions"] == 0
