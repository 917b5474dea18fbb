"""Local shape features per vertex for the initial classification (thesis 4.1.1).

For each vertex and a neighbourhood radius r (relative to the object's size):

- shift to mean: distance from the vertex to the mean of its neighbours, divided by r
  (large at edges such as a rim);
- radius scale: number of neighbours within r over the number within 2 r (about 1/4 on a
  surface, 1/2 on a "1D" structure such as a handle);
- ordered eigenvalues: eigenvalues of the neighbours' covariance, descending, divided by
  r^2.

The features of several radii are concatenated. Neighbourhoods come from a KD-tree over the
vertices. Vertex density enters the counts only through ratios, so meshes of different
resolution give comparable features.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.spatial import cKDTree

DEFAULT_RADII = (0.04, 0.08)  # fractions of the bounding-box diagonal


def local_features(
    vertices: np.ndarray, radii: tuple[float, ...] = DEFAULT_RADII, max_points: int = 6000
) -> np.ndarray:
    """Shift to mean, radius scale and ordered eigenvalues for every vertex.

    Args:
        vertices: (V, 3) positions in m.
        radii: neighbourhood radii as fractions of the bounding-box diagonal.
        max_points: neighbourhoods are taken among at most this many vertices (a random,
            seeded subset), which bounds the cost on dense meshes.

    Returns:
        (V, 5 * len(radii)) features.
    """
    v = np.asarray(vertices, dtype=float)
    diag = float(np.linalg.norm(np.ptp(v, axis=0)))
    support = v
    if len(v) > max_points:
        support = v[np.random.default_rng(0).choice(len(v), max_points, replace=False)]
    tree = cKDTree(support)
    outer = (support[:, :, None] * support[:, None, :]).reshape(-1, 9)
    columns = []
    for frac in radii:
        r = frac * diag
        near = tree.query_ball_point(v, r, workers=-1)
        counts = np.array([len(i) for i in near])
        count_2r = tree.query_ball_point(v, 2 * r, workers=-1, return_length=True)
        # Neighbour sums as one sparse product instead of a Python loop per vertex.
        rows = np.repeat(np.arange(len(v)), counts)
        adj = csr_matrix(
            (np.ones(len(rows)), (rows, np.concatenate(near).astype(np.int64))),
            shape=(len(v), len(support)),
        )
        n = np.maximum(counts, 1)[:, None]
        mu = adj @ support / n
        second = (adj @ outer / n).reshape(-1, 3, 3)
        cov = second - mu[:, :, None] * mu[:, None, :]
        eig = np.linalg.eigvalsh(cov)[:, ::-1] / r**2
        shift = np.linalg.norm(v - mu, axis=1) / r
        ratio = counts / np.maximum(count_2r, 1)
        sparse = counts < 3
        shift[sparse], ratio[sparse], eig[sparse] = 0.0, 0.0, 0.0
        columns += [shift[:, None], ratio[:, None], eig]
    return np.hstack(columns)
