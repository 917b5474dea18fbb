"""Chapter 4: local features, the canonical frame and label transfer on the thesis objects.

Targets (issue 3), source red cup, method "best": mean per-part IoU >= 0.85 for rim and
container and >= 0.7 for the handle; the thesis method runs and is reported.
"""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pour_gym.assets import label_container, part_iou
from pour_gym.errors import InputError
from pour_gym.objects import OBJECT_NAMES
from pour_gym.parts import Part
from pour_gym.warp.local_features import local_features
from pour_gym.warp.transfer import transfer_best


def test_local_features_of_a_plane_and_a_line():
    g = np.stack(np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 201)), -1).reshape(-1, 2)
    plane = np.column_stack([g, np.zeros(len(g))])
    f = local_features(plane, radii=(0.05,), max_points=50000)
    centre = np.linalg.norm(plane[:, :2] - 0.5, axis=1) < 0.1
    shift, ratio, eig = f[centre, 0], f[centre, 1], f[centre, 2:5]
    assert np.abs(shift).max() < 0.02  # flat: the neighbours' mean is the point itself
    assert ratio.mean() == pytest.approx(0.25, rel=0.05)  # pi r^2 / pi (2r)^2
    # A uniform disc of radius r has variance r^2 / 4 along each in-plane axis.
    assert eig[:, 0].mean() == pytest.approx(0.25, rel=0.05)
    assert eig[:, 1].mean() == pytest.approx(0.25, rel=0.05)
    assert np.abs(eig[:, 2]).max() < 1e-9
    line = np.column_stack([np.linspace(0, 1, 2001), np.zeros(2001), np.zeros(2001)])
    fl = local_features(line, radii=(0.05,), max_points=5000)
    assert fl[800:1200, 1].mean() == pytest.approx(0.5, rel=0.05)  # 2r / 4r
    # At the end of the line the neighbours lie to one side: shift to mean is r / 2.
    assert fl[0, 0] == pytest.approx(0.5, rel=0.05)


@pytest.fixture(scope="module")
def labelled():
    return {
        (name, method): label_container(name, "red_cup", method)
        for name in OBJECT_NAMES
        for method in ("best", "thesis")
    }


def mean_iou(labelled, method, part):
    values = [labelled[(n, method)].meta["iou"][part] for n in OBJECT_NAMES]
    return float(np.mean([v for v in values if v is not None]))


@pytest.mark.parametrize(("part", "target"), [("rim", 0.85), ("container", 0.85), ("handle", 0.7)])
def test_best_method_meets_the_iou_targets(labelled, part, target):
    assert mean_iou(labelled, "best", part) >= target


def test_thesis_method_runs_and_is_reported(labelled):
    for name in OBJECT_NAMES:
        meta = labelled[(name, "thesis")].meta
        assert set(meta["iou"]) == {"outside", "rim", "handle", "container"}
        assert meta["source"]["method"] == "thesis"
    # The better method is better where the thesis says its own fails.
    assert mean_iou(labelled, "best", "rim") > mean_iou(labelled, "thesis", "rim")


@pytest.mark.parametrize(
    ("key", "target"), [("height", 0.03), ("rim_radius", 0.03), ("volume", 0.10)]
)
def test_tables_4_1_to_4_3_beat_the_thesis(labelled, key, target):
    errors = [labelled[(n, "best")].meta["tables"][key]["rel_error"] for n in OBJECT_NAMES]
    thesis = [labelled[(n, "best")].meta["tables"][key]["thesis_rel_error"] for n in OBJECT_NAMES]
    assert np.mean(errors) <= target
    assert np.mean(errors) < np.mean(thesis)


def test_bowls_have_no_handle(labelled):
    for name in ("standard_bowl", "square_bowl"):
        asset = labelled[(name, "best")]
        assert not np.any(asset.labels == Part.HANDLE)
        assert asset.meta["iou"]["handle"] is None


def perturbed(models, name, seed):
    """The object rotated at random, moved, scaled by 1.4, remeshed to 4x vertices, noisy."""
    model = models[name]
    v, f = trimesh.remesh.subdivide(model.mesh.vertices, model.mesh.faces)
    mesh = trimesh.Trimesh(v, f, process=False)
    labels = np.concatenate([model.labels, np.zeros(len(v) - len(model.labels), dtype=np.int8)])
    # New midpoint vertices take the label of their nearest original vertex.
    from scipy.spatial import cKDTree

    _, near = cKDTree(model.mesh.vertices).query(v)
    labels = model.labels[near]
    rng = np.random.default_rng(seed)
    mesh.vertices = mesh.vertices + rng.normal(0, 2e-4, size=mesh.vertices.shape)
    transform = np.eye(4)
    transform[:3, :3] = Rotation.random(random_state=seed).as_matrix() * 1.4
    transform[:3, 3] = rng.uniform(-1, 1, 3)
    mesh.apply_transform(transform)
    return mesh, labels


@pytest.mark.parametrize(
    ("name", "seed"), [("broad_cup", 1), ("high_cup", 2), ("standard_bowl", 3)]
)
@pytest.mark.slow
def test_robust_to_pose_scale_resolution_and_noise(models, name, seed):
    source = models["red_cup"]
    mesh, truth = perturbed(models, name, seed)
    assert len(mesh.vertices) > 3 * len(models[name].mesh.vertices)
    result = transfer_best(source.mesh, source.labels, mesh)
    iou = part_iou(result.labels, truth)
    assert iou["rim"] > 0.8 and iou["container"] > 0.9
    if models[name].spec.handle:
        assert iou["handle"] > 0.8
    else:
        assert iou["handle"] is None
    # The frame undoes the pose: upright, height in the scaled metres.
    assert result.frame.height == pytest.approx(1.4 * models[name].spec.height, rel=0.03)


def test_degenerate_and_tiny_meshes_are_refused():
    flat = trimesh.Trimesh(
        [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.3, 0, 0]], [[0, 1, 2], [1, 2, 3]]
    )
    with pytest.raises(InputError, match="degenerate"):
        label_container(flat)
    tiny = trimesh.creation.icosphere(radius=0.001)
    with pytest.raises(InputError, match="units"):
        label_container(tiny)
    with pytest.raises(InputError, match="method"):
        label_container("red_cup", method="magic")
    with pytest.raises(InputError, match="catalogue"):
        label_container("no_such_cup")


def test_a_closed_solid_is_not_a_container():
    with pytest.raises(InputError, match="holds no water"):
        label_container(trimesh.creation.box([0.08, 0.08, 0.08]))
