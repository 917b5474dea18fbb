"""The thesis's classifiers against closed checks (no scikit-learn)."""

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.stats import multivariate_normal

from pour_gym.warp.classifiers import GaussianGenerative, LogisticRegression


@pytest.fixture
def data():
    rng = np.random.default_rng(0)
    x0 = rng.normal([0, 0], [1.0, 0.5], size=(300, 2))
    x1 = rng.normal([1.5, 1.0], [0.7, 1.2], size=(200, 2))
    x = np.vstack([x0, x1])
    t = np.r_[np.zeros(300), np.ones(200)]
    return x, t


def test_newton_raphson_reaches_the_regularised_optimum(data):
    x, t = data
    lam = 0.5
    clf = LogisticRegression(lam=lam).fit(x, t)
    phi = clf._phi(x)
    y = clf.predict_proba(x)
    penalty = lam * clf.w.copy()
    penalty[0] = 0.0
    # The gradient of the regularised cross-entropy vanishes at the fitted weights.
    assert np.abs(phi.T @ (y - t) + penalty).max() < 1e-8
    assert clf.iterations < 15  # Newton converges quadratically

    def objective(w):
        a = phi @ w
        return np.sum(np.logaddexp(0, a) - t * a) + 0.5 * lam * np.sum(w[1:] ** 2)

    ref = minimize(objective, np.zeros(3), method="BFGS", options={"gtol": 1e-10}).x
    assert np.allclose(clf.w, ref, atol=1e-5)


def test_logistic_regression_larger_lambda_gives_smaller_weights(data):
    x, t = data
    small = LogisticRegression(lam=1e-3).fit(x, t)
    large = LogisticRegression(lam=100.0).fit(x, t)
    assert np.linalg.norm(large.w[1:]) < np.linalg.norm(small.w[1:])


def test_generative_classifier_is_bayes_rule_on_ml_gaussians(data):
    x, t = data
    clf = GaussianGenerative(reg=0.0).fit(x, t)
    z = (x - clf.mean) / clf.scale
    for k, cls in enumerate((0, 1)):
        zc = z[t == cls]
        assert np.allclose(clf.mu[k], zc.mean(axis=0))
        assert np.allclose(clf.cov[k], np.cov(zc.T, bias=True))  # 1/n, as in the thesis
    assert np.allclose(clf.prior, [0.6, 0.4])
    q = np.array([[0.0, 0.0], [1.5, 1.0], [3.0, -1.0]])
    zq = (q - clf.mean) / clf.scale
    p1 = multivariate_normal(clf.mu[1], clf.cov[1]).pdf(zq) * 0.4
    p0 = multivariate_normal(clf.mu[0], clf.cov[0]).pdf(zq) * 0.6
    assert np.allclose(clf.predict_proba(q), p1 / (p0 + p1))


def test_generative_classifier_needs_both_classes():
    with pytest.raises(ValueError, match="both classes"):
        GaussianGenerative().fit(np.zeros((5, 2)), np.ones(5))
