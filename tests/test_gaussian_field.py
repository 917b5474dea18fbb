"""The kernel regression against dense closed forms on small problems."""

import numpy as np
import pytest

from pour_gym.mesh.gaussian_field import fit_gaussian_field, kernel_matrix, voxel_means


def dense_kernel(x, y, sigma, cutoff):
    d = np.linalg.norm(x[:, None] - y[None], axis=-1)
    r0, r1 = (cutoff - 1) * sigma, cutoff * sigma
    u = np.clip((r1 - d) / (r1 - r0), 0.0, 1.0)
    taper = np.where(d <= r0, 1.0, u * u * (3 - 2 * u))
    return np.exp(-(d**2) / (2 * sigma**2)) * taper


@pytest.fixture
def cloud():
    rng = np.random.default_rng(1)
    # Points on a sphere of radius 3 cm.
    p = rng.normal(size=(600, 3))
    return 0.03 * p / np.linalg.norm(p, axis=1, keepdims=True)


def test_sparse_kernel_matrix_equals_dense(cloud):
    K = kernel_matrix(cloud, sigma=0.01, cutoff=4.0).toarray()
    assert np.allclose(K, dense_kernel(cloud, cloud, 0.01, 4.0), atol=1e-12)
    assert np.allclose(K, K.T)
    assert np.allclose(np.diag(K), 1.0)


def test_fit_solves_the_regularised_system(cloud):
    reg = 1e-3
    field = fit_gaussian_field(cloud, sigma=0.01, regularization=reg)
    K = dense_kernel(cloud, cloud, 0.01, 4.0)
    lam = reg * K.sum(axis=1)
    A = K + np.diag(lam)
    ones = np.ones(len(cloud))
    # Conjugate gradients stop at a relative residual of 1e-6.
    assert np.linalg.norm(A @ field.alpha - ones) <= 1e-6 * np.linalg.norm(ones) * 1.01
    alpha = np.linalg.solve(A, ones)
    # y(x) = k(x)^T alpha, evaluated away from the data as well.
    q = np.random.default_rng(2).uniform(-0.05, 0.05, size=(200, 3))
    kq = dense_kernel(q, cloud, 0.01, 4.0)
    assert np.allclose(field(q), kq @ field.alpha, atol=1e-12)
    assert np.allclose(field(q), kq @ alpha, atol=1e-4)
    # At the data the fit reaches about 1 / (1 + reg), above tau = 0.99.
    assert np.all(field(cloud) > 0.99)


def test_voxel_means_average_each_voxel():
    pts = np.array([[0.0, 0, 0], [0.001, 0, 0], [0.011, 0, 0], [0.019, 0, 0]])
    means = voxel_means(pts, 0.01)
    assert sorted(means[:, 0].round(6)) == [0.0005, 0.015]
