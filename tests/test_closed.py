"""A container whose opening a scan closed is refused, with the fix, wherever it enters."""

import gymnasium as gym
import numpy as np
import pytest
import trimesh

import pour_gym  # noqa: F401 - registers the environments
from pour_gym.assets import LabelledAsset, label_container, write_asset
from pour_gym.errors import ClosedContainerError
from pour_gym.objects import cylinder_cup
from pour_gym.objects.user_meshes import capped_cup


@pytest.mark.parametrize("dented_base", [False, True])
def test_a_capped_cup_is_refused_with_the_fix(dented_base):
    with pytest.raises(ClosedContainerError, match="cut the cap off at the rim") as err:
        label_container(capped_cup(dented_base=dented_base))
    assert "--allow-closed" in str(err.value)


def test_the_command_line_refuses_it_in_one_line(tmp_path, cli):
    path = tmp_path / "pitcher.stl"
    capped_cup(dented_base=True).export(path)
    for args in (("label", str(path), "--out", str(tmp_path / "a")), ("measure", str(path))):
        proc = cli(*args, check=False)
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "looks closed at the top" in lines[0], proc.stderr
        assert "Traceback" not in proc.stderr


def test_environments_refuse_a_closed_container_however_it_was_labelled(tmp_path):
    # An asset of a cup with a lid laid on its rim (two bodies, not watertight), written
    # as `label --allow-closed` would write it.
    cup = label_container(cylinder_cup(0.035, 0.09))
    lid = trimesh.creation.cylinder(radius=0.04, height=0.003)
    lid.apply_translation([0.0, 0.0, cup.geometry.height + 0.0015])
    mesh = trimesh.util.concatenate([cup.mesh, lid])
    labels = np.concatenate([cup.labels, np.zeros(len(lid.vertices), np.int8)])
    closed = LabelledAsset("lidded", mesh, labels, cup.geometry, dict(cup.meta, closed="lid"))
    folder = write_asset(closed, tmp_path / "lidded", picture=False)
    with pytest.raises(ClosedContainerError, match="looks closed"):
        label_container(mesh)
    for env_id in ("PourGym/Pour-v0", "PourGym/TiltPour-v0", "PourGym/ParticleDrop-v0"):
        with pytest.raises(ClosedContainerError, match="looks closed"):
            gym.make(env_id, objects=[str(folder)])
