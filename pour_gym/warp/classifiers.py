"""The two classifiers of thesis 4.1.2, written out as the thesis gives them.

- :class:`LogisticRegression`: ``p(C1|x) = sigmoid(w^T phi(x))`` with ``phi(x) = [1, x]``,
  fitted by Newton-Raphson (iteratively reweighted least squares) on the L2-regularised
  cross-entropy: ``grad = Phi^T (y - t) + lambda w``, ``H = Phi^T R Phi + lambda I``,
  ``w <- w - H^-1 grad`` until the step is below a tolerance (Bishop 2006, 4.3.3).
- :class:`GaussianGenerative`: one multivariate normal per class (maximum-likelihood mean
  and covariance) and class priors, combined by Bayes' rule.

Both take standardised inputs: features are centred and scaled by the training set's
statistics, which the fitted object keeps, so callers pass raw features.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _sigmoid(a: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * a))  # stable for large |a|


@dataclass
class LogisticRegression:
    """Two-class logistic regression fitted by Newton-Raphson with an L2 penalty.

    Attributes:
        lam: regularisation lambda (the bias is not penalised).
        max_iter: Newton iterations at most.
        tol: stop when the largest weight change is below this.
        w: fitted weights ``[bias, w_1 .. w_M]`` on standardised features.
        mean: feature means of the training set.
        scale: feature standard deviations of the training set.
        iterations: Newton iterations the fit took.
    """

    lam: float = 1e-3
    max_iter: int = 100
    tol: float = 1e-8
    w: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mean: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scale: np.ndarray = field(default_factory=lambda: np.ones(0))
    iterations: int = 0

    def _phi(self, x: np.ndarray) -> np.ndarray:
        z = (np.asarray(x, dtype=float) - self.mean) / self.scale
        return np.column_stack([np.ones(len(z)), z])

    def fit(self, x: np.ndarray, t: np.ndarray) -> LogisticRegression:
        """Fit on features ``x`` (N, M) and targets ``t`` (N,) in {0, 1}."""
        x = np.asarray(x, dtype=float)
        t = np.asarray(t, dtype=float)
        if x.ndim == 1:
            x = x[:, None]
        self.mean = x.mean(axis=0)
        self.scale = np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0)
        phi = self._phi(x)
        m = phi.shape[1]
        penalty = self.lam * np.eye(m)
        penalty[0, 0] = 0.0
        w = np.zeros(m)
        for i in range(1, self.max_iter + 1):
            y = _sigmoid(phi @ w)
            grad = phi.T @ (y - t) + penalty @ w
            r = y * (1.0 - y)
            hess = (phi * r[:, None]).T @ phi + penalty + 1e-12 * np.eye(m)
            step = np.linalg.solve(hess, grad)
            w = w - step
            self.iterations = i
            if np.max(np.abs(step)) < self.tol:
                break
        self.w = w
        return self

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """p(C1 | x) for each row of ``x``."""
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            x = x[:, None]
        return _sigmoid(self._phi(x) @ self.w)

    def to_dict(self) -> dict:
        """Fitted parameters, JSON-serialisable."""
        return {
            "lam": self.lam,
            "w": self.w.tolist(),
            "mean": self.mean.tolist(),
            "scale": self.scale.tolist(),
        }


@dataclass
class GaussianGenerative:
    """Class-conditional Gaussians with priors, classified by Bayes' rule.

    Attributes:
        reg: added to the covariances' diagonals (in standardised units) to keep them
            invertible.
        mu: (2, M) class means (class 0, class 1).
        cov: (2, M, M) class covariances.
        prior: (2,) class priors.
    """

    reg: float = 1e-6
    mu: np.ndarray = field(default_factory=lambda: np.zeros((2, 0)))
    cov: np.ndarray = field(default_factory=lambda: np.zeros((2, 0, 0)))
    prior: np.ndarray = field(default_factory=lambda: np.full(2, 0.5))
    mean: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scale: np.ndarray = field(default_factory=lambda: np.ones(0))

    def fit(self, x: np.ndarray, t: np.ndarray) -> GaussianGenerative:
        """Fit on features ``x`` (N, M) and targets ``t`` (N,) in {0, 1}."""
        x = np.asarray(x, dtype=float)
        t = np.asarray(t).astype(bool)
        if t.all() or not t.any():
            raise ValueError("the generative classifier needs examples of both classes")
        self.mean = x.mean(axis=0)
        self.scale = np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0)
        z = (x - self.mean) / self.scale
        mus, covs = [], []
        for cls in (False, True):
            zc = z[t == cls]
            mu = zc.mean(axis=0)
            d = zc - mu
            # Maximum likelihood: 1/n, as in the thesis.
            covs.append(d.T @ d / len(zc) + self.reg * np.eye(z.shape[1]))
            mus.append(mu)
        self.mu, self.cov = np.array(mus), np.array(covs)
        self.prior = np.array([np.mean(~t), np.mean(t)])
        return self

    def _log_likelihood(self, z: np.ndarray, k: int) -> np.ndarray:
        d = z - self.mu[k]
        _, logdet = np.linalg.slogdet(self.cov[k])
        maha = np.einsum("ij,ij->i", d @ np.linalg.inv(self.cov[k]), d)
        return -0.5 * (maha + logdet + z.shape[1] * np.log(2.0 * np.pi))

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """p(C1 | x) by Bayes' rule, for each row of ``x``."""
        z = (np.asarray(x, dtype=float) - self.mean) / self.scale
        a0 = self._log_likelihood(z, 0) + np.log(self.prior[0])
        a1 = self._log_likelihood(z, 1) + np.log(self.prior[1])
        return _sigmoid(a1 - a0)
