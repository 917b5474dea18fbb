"""Bad input gets a clear message, never a deep traceback or a silently wrong result."""

import numpy as np
import pytest
import trimesh

from pour_gym.errors import InputError
from pour_gym.mesh.fileio import load_mesh, load_point_cloud, save_point_cloud, validate_mesh
from pour_gym.mesh.reconstruct import reconstruct, validate_cloud
from pour_gym.mesh.scan import PointCloud


def sphere_cloud(n=2000, radius=0.04):
    p = np.random.default_rng(0).normal(size=(n, 3))
    return radius * p / np.linalg.norm(p, axis=1, keepdims=True)


@pytest.mark.parametrize(
    ("points", "message"),
    [
        (np.zeros((0, 3)), "empty"),
        (np.zeros((10, 2)), r"\(N, 3\)"),
        (np.full((500, 3), np.nan), "NaN"),
        (sphere_cloud(50), "at least 100"),
        (sphere_cloud() * 1000, "millimetres"),
        (sphere_cloud() * 0.01, "units"),
    ],
)
def test_bad_clouds(points, message):
    with pytest.raises(InputError, match=message):
        validate_cloud(points)
    with pytest.raises(InputError, match=message):
        reconstruct(points)


def test_one_nan_point_is_reported_with_its_count():
    pts = sphere_cloud()
    pts[7, 1] = np.nan
    with pytest.raises(InputError, match="1 points with NaN"):
        reconstruct(pts)


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".xyz", ".npy"])
def test_point_cloud_files_round_trip(tmp_path, suffix):
    pts = sphere_cloud(300)
    normals = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    path = save_point_cloud(PointCloud(pts, normals), tmp_path / f"c{suffix}")
    back = load_point_cloud(path)
    assert np.allclose(back.points, pts, atol=1e-6)
    assert back.normals is not None and np.allclose(back.normals, normals, atol=1e-6)
    mm = load_point_cloud(path, scale=1000.0)
    assert np.allclose(mm.points, pts * 1000, atol=1e-3)


def test_missing_and_unsupported_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_point_cloud(tmp_path / "nope.ply")
    bad = tmp_path / "cloud.las"
    bad.write_text("x")
    with pytest.raises(InputError, match="not supported"):
        load_point_cloud(bad)
    empty = tmp_path / "empty.xyz"
    empty.write_text("")
    with pytest.raises(InputError):
        load_point_cloud(empty)
    wrong = tmp_path / "wrong.npy"
    np.save(wrong, np.zeros((4, 4)))
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        load_point_cloud(wrong)


def test_bad_meshes(tmp_path):
    box = trimesh.creation.box([0.05, 0.05, 0.05])
    validate_mesh(box, watertight=True)
    with pytest.raises(InputError, match="millimetres"):
        validate_mesh(trimesh.creation.box([50.0, 50.0, 50.0]))
    flat = trimesh.Trimesh(
        [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.3, 0, 0]], [[0, 1, 2], [1, 2, 3]]
    )
    with pytest.raises(InputError, match="degenerate"):
        validate_mesh(flat)
    open_box = box.copy()
    open_box.update_faces(np.arange(len(box.faces)) > 1)
    with pytest.raises(InputError, match="not watertight"):
        validate_mesh(open_box, watertight=True)
    path = tmp_path / "box.obj"
    box.export(path)
    assert len(load_mesh(path).faces) == 12
    with pytest.raises(InputError, match="not found"):
        load_mesh(tmp_path / "missing.stl")
