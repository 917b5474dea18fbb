"""The built wheel carries the subpackages and the asset files."""

import subprocess
import sys
import zipfile

import pytest

from pour_gym.assets import real_mesh_path


@pytest.mark.slow
def test_wheel_contents(tmp_path):
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            ".",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("pour_gym-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for required in [
        "pour_gym/__init__.py",
        "pour_gym/envs/__init__.py",
        "pour_gym/agents/__init__.py",
        "pour_gym/asset_files/ycb/025_mug.obj",
        "pour_gym/asset_files/ycb/024_bowl.obj",
        "pour_gym/asset_files/ycb/README.md",
    ]:
        assert required in names, required
    assert not any(n.startswith(("envs/", "agents/", "assets/", "tests/")) for n in names)
    # Every module of the source tree is in the wheel (a subpackage missing from the
    # package list would install without error and fail on import).
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    for source in (root / "pour_gym").rglob("*.py"):
        assert source.relative_to(root).as_posix() in names, source
    for name in ("red_cup", "ycb_mug", "pybullet_mug"):
        for file in ("mesh.obj", "labels.npy", "meta.json"):
            assert f"pour_gym/asset_files/{name}/{file}" in names
    # The trained models ship whole: what evaluate loads beside model.zip included.
    shipped = sorted((root / "agents" / "models").glob("*/model.zip"))
    assert shipped, "no trained model in agents/models"
    for model in shipped:
        for file in ("model.zip", "config.json", "vecnormalize.pkl"):
            assert f"pour_gym/agents/models/{model.parent.name}/{file}" in names


def test_packaged_meshes_resolve():
    import pour_gym.agents
    import pour_gym.envs

    assert isinstance(pour_gym.envs.ENV_IDS, tuple)
    assert real_mesh_path("ycb_mug").is_file()
