"""The simulated turntable scan."""

import numpy as np
import pytest

from pour_gym.errors import InputError
from pour_gym.mesh.scan import ScanConfig, turntable_scan
from pour_gym.parts import Part


def test_scan_sees_only_the_outside(models):
    cup = models["red_cup"]
    cloud = turntable_scan(cup.mesh, cup.labels, ScanConfig(noise=0.0))
    v, labels = cup.mesh.vertices, cup.labels
    from scipy.spatial import cKDTree

    _, idx = cKDTree(v).query(cloud.points)
    seen = np.bincount(labels[idx], minlength=4)
    assert seen[Part.CONTAINER] / len(cloud.points) < 0.02
    assert seen[Part.OUTSIDE] > 0 and seen[Part.HANDLE] > 0 and seen[Part.RIM] > 0
    # No point below the base: the turntable hides it.
    assert cloud.points[:, 2].min() > -1e-6
    # Normals point out of the object: away from the axis on the side wall.
    side = (cloud.points[:, 2] > 0.03) & (cloud.points[:, 2] < 0.06) & (cloud.points[:, 0] < 0)
    radial = cloud.points[side, :2] / np.linalg.norm(cloud.points[side, :2], axis=1)[:, None]
    assert np.mean(np.sum(cloud.normals[side, :2] * radial, axis=1) > 0.8) > 0.95


def test_noise_is_gaussian_along_the_ray(models):
    cup = models["red_cup"]
    cfg = ScanConfig(noise=0.0, views=4, elevations_deg=(5.0,))
    clean = turntable_scan(cup.mesh, cup.labels, cfg).points
    noisy = turntable_scan(
        cup.mesh, cup.labels, ScanConfig(noise=0.001, views=4, elevations_deg=(5.0,))
    ).points
    assert clean.shape == noisy.shape
    assert np.std(np.linalg.norm(noisy - clean, axis=1)) == pytest.approx(0.001 * 0.6, rel=0.25)
    assert np.median(np.linalg.norm(noisy - clean, axis=1)) == pytest.approx(0.001 * 0.674, rel=0.1)


def test_same_seed_same_cloud(models):
    cup = models["very_small_cup"]
    a = turntable_scan(cup.mesh, cup.labels, ScanConfig(seed=3))
    b = turntable_scan(cup.mesh, cup.labels, ScanConfig(seed=3))
    c = turntable_scan(cup.mesh, cup.labels, ScanConfig(seed=4))
    assert np.array_equal(a.points, b.points)
    assert not np.array_equal(a.points, c.points)


def test_scanning_nothing_is_an_error(models):
    import trimesh

    with pytest.raises(InputError, match="empty"):
        turntable_scan(trimesh.Trimesh())
