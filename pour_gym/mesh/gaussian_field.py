"""Gaussian-kernel implicit surface regression (thesis 3.2), scaled to large clouds.

The thesis fits ``y(x) = k(x)^T alpha`` with ``alpha = (K + lambda I)^-1 t``, a Gaussian
kernel ``k(x, x') = exp(-|x - x'|^2 / (2 sigma^2))`` and targets ``t = 1`` at every
point (all training points lie in the object). The object is where ``y(x) > tau``.

A dense N x N kernel matrix is out of the question for a 50k-point scan (20 GB), so this
module makes three approximations, each standard:

1. Inducing points: the cloud is averaged on a voxel grid of ``spacing`` (a few mm, well
   below sigma = 1 cm) and the regression is fitted on the voxel means. This also averages
   the sensor noise.
2. A compactly supported kernel: the Gaussian is tapered smoothly to zero between
   ``(cutoff - 1) * sigma`` and ``cutoff * sigma`` (3 and 4 sigma by default), so K is
   sparse; a numba cell list builds it in CSR form. A hard cut would leave seams in the
   field where points cross the cut-off sphere (a few per cent at 3 sigma, enough to punch
   holes in a surface at tau = 0.99).
3. An iterative solver: ``(K + lambda I) alpha = t`` is solved by conjugate gradients, never
   by factorising K.

Memory is then O(M * neighbours) for M inducing points, independent of the scan's size.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numba as nb
import numpy as np
from scipy.sparse import csr_matrix, diags
from scipy.sparse.linalg import cg

from pour_gym.io.numba_threads import FORK_WARNING, threads_usable, twin, use_wheel_tbb

# numba falls back from TBB to its other threading layers by itself; on machines with an
# old TBB it says so on every first parallel call, which is noise for users.
warnings.filterwarnings("ignore", message="The TBB threading layer requires TBB")


@nb.njit(cache=True)
def _cell_sort(points: np.ndarray, origin: np.ndarray, cell: float, dims: np.ndarray):
    """Counting sort of points into cubic cells: (order, start offsets per cell)."""
    n = points.shape[0]
    n_cells = dims[0] * dims[1] * dims[2]
    key = np.empty(n, dtype=np.int64)
    count = np.zeros(n_cells + 1, dtype=np.int64)
    for i in range(n):
        cx = int((points[i, 0] - origin[0]) / cell)
        cy = int((points[i, 1] - origin[1]) / cell)
        cz = int((points[i, 2] - origin[2]) / cell)
        k = (cx * dims[1] + cy) * dims[2] + cz
        key[i] = k
        count[k + 1] += 1
    for k in range(n_cells):
        count[k + 1] += count[k]
    order = np.empty(n, dtype=np.int64)
    fill = count[:-1].copy()
    for i in range(n):
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    return order, count


@nb.njit(cache=True)
def _kernel(d2: float, inv2s2: float, r0: float, r1: float) -> float:
    """Gaussian times a smoothstep taper from 1 at distance r0 to 0 at r1."""
    g = np.exp(-d2 * inv2s2)
    if d2 <= r0 * r0:
        return g
    u = (r1 - np.sqrt(d2)) / (r1 - r0)
    return g * u * u * (3.0 - 2.0 * u)


@nb.njit(cache=True)
def _neighbour_cells(q, origin, cell, dims):
    """Cell coordinates of a query point (clamped into the grid)."""
    cx = min(max(int((q[0] - origin[0]) / cell), 0), dims[0] - 1)
    cy = min(max(int((q[1] - origin[1]) / cell), 0), dims[1] - 1)
    cz = min(max(int((q[2] - origin[2]) / cell), 0), dims[2] - 1)
    return cx, cy, cz


def _kernel_sum_loop(queries, points, weights, order, start, origin, cell, dims, inv2s2, r0):
    """sum_j weights_j * k(q, p_j) over the p_j within the cut-off ``cell``."""
    r2max = cell * cell
    out = np.zeros(queries.shape[0])
    for i in nb.prange(queries.shape[0]):
        q = queries[i]
        cx, cy, cz = _neighbour_cells(q, origin, cell, dims)
        acc = 0.0
        for x in range(max(cx - 1, 0), min(cx + 2, dims[0])):
            for y in range(max(cy - 1, 0), min(cy + 2, dims[1])):
                for z in range(max(cz - 1, 0), min(cz + 2, dims[2])):
                    k = (x * dims[1] + y) * dims[2] + z
                    for s in range(start[k], start[k + 1]):
                        j = order[s]
                        dx = q[0] - points[j, 0]
                        dy = q[1] - points[j, 1]
                        dz = q[2] - points[j, 2]
                        d2 = dx * dx + dy * dy + dz * dz
                        if d2 < r2max:
                            acc += weights[j] * _kernel(d2, inv2s2, r0, cell)
        out[i] = acc
    return out


def _kernel_rows_loop(points, order, start, origin, cell, dims, inv2s2, r0, counts, indptr):
    """Column indices and values of the truncated kernel matrix (CSR), in two passes.

    With ``indptr`` empty the first pass only counts each row's entries into ``counts``.
    """
    n = points.shape[0]
    r2max = cell * cell
    fill = indptr.shape[0] > 0
    indices = np.empty(indptr[-1] if fill else 0, dtype=np.int64)
    data = np.empty(indptr[-1] if fill else 0)
    for i in nb.prange(n):
        q = points[i]
        cx, cy, cz = _neighbour_cells(q, origin, cell, dims)
        c = 0
        for x in range(max(cx - 1, 0), min(cx + 2, dims[0])):
            for y in range(max(cy - 1, 0), min(cy + 2, dims[1])):
                for z in range(max(cz - 1, 0), min(cz + 2, dims[2])):
                    k = (x * dims[1] + y) * dims[2] + z
                    for s in range(start[k], start[k + 1]):
                        j = order[s]
                        dx = q[0] - points[j, 0]
                        dy = q[1] - points[j, 1]
                        dz = q[2] - points[j, 2]
                        d2 = dx * dx + dy * dy + dz * dz
                        if d2 < r2max:
                            if fill:
                                indices[indptr[i] + c] = j
                                data[indptr[i] + c] = _kernel(d2, inv2s2, r0, cell)
                            c += 1
        counts[i] = c
    return indices, data


def _compiled(loop) -> dict:
    """A loop compiled with parallel threads (True) and for one thread (False)."""
    return {
        True: nb.njit(parallel=True, cache=True)(loop),
        False: nb.njit(cache=True)(twin(loop, "_serial")),
    }


_KERNEL_SUM = _compiled(_kernel_sum_loop)
_KERNEL_ROWS = _compiled(_kernel_rows_loop)


def _threaded() -> bool:
    """Whether the parallel builds may run here (see :mod:`pour_gym.io.numba_threads`).

    Loads the wheel's TBB first (once): numba starts its threading layer at the first
    parallel loop, and the layer it finds then is the one the process keeps.
    """
    use_wheel_tbb()
    if threads_usable():
        return True
    warnings.warn(FORK_WARNING.format(what="the Gaussian field"), RuntimeWarning, stacklevel=3)
    return False


@dataclass
class GaussianField:
    """A fitted implicit surface ``y(x) = sum_j alpha_j k(x, c_j)``.

    Attributes:
        centres: (M, 3) inducing points in m.
        alpha: (M,) weights.
        sigma: kernel width in m.
        cutoff: the kernel is tapered to zero between ``(cutoff - 1) * sigma`` and
            ``cutoff * sigma``.
        cg_iterations: conjugate-gradient iterations the fit took.
    """

    centres: np.ndarray
    alpha: np.ndarray
    sigma: float
    cutoff: float
    cg_iterations: int
    _grid: tuple | None = None

    def _cells(self) -> tuple:
        if self._grid is None:
            self._grid = _build_cells(self.centres, self.cutoff * self.sigma)
        return self._grid

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Evaluate the field at (Q, 3) positions in m."""
        order, start, origin, cell, dims = self._cells()
        return _KERNEL_SUM[_threaded()](
            np.ascontiguousarray(x, dtype=np.float64),
            self.centres,
            self.alpha,
            order,
            start,
            origin,
            cell,
            dims,
            1.0 / (2.0 * self.sigma**2),
            (self.cutoff - 1.0) * self.sigma,
        )


def _build_cells(points: np.ndarray, cell: float) -> tuple:
    """Cell list of ``points`` with cubic cells of edge ``cell``."""
    origin = points.min(axis=0) - 1e-9
    dims = (np.floor((points.max(axis=0) - origin) / cell).astype(np.int64) + 1).astype(np.int64)
    order, start = _cell_sort(points, origin, cell, dims)
    return order, start, origin, float(cell), dims


def voxel_means(points: np.ndarray, spacing: float) -> np.ndarray:
    """Mean of the points in each occupied voxel of edge ``spacing`` (inducing points).

    Args:
        points: (N, 3) positions in m.
        spacing: voxel edge in m.

    Returns:
        (M, 3) means, one per occupied voxel, in a deterministic order.
    """
    keys = np.floor((points - points.min(axis=0)) / spacing).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse, points)
    return sums / counts[:, None]


def kernel_matrix(points: np.ndarray, sigma: float, cutoff: float = 4.0) -> csr_matrix:
    """Sparse tapered Gaussian kernel matrix, zero beyond ``cutoff * sigma``.

    Args:
        points: (M, 3) positions in m.
        sigma: kernel width in m.
        cutoff: radius in units of sigma where the taper (over the last sigma) reaches 0.

    Returns:
        The symmetric (M, M) matrix in CSR form.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    order, start, origin, cell, dims = _build_cells(pts, cutoff * sigma)
    args = (pts, order, start, origin, cell, dims, 1.0 / (2 * sigma**2), (cutoff - 1.0) * sigma)
    counts = np.zeros(len(pts), dtype=np.int64)
    kernel_rows = _KERNEL_ROWS[_threaded()]
    kernel_rows(*args, counts, np.zeros(0, dtype=np.int64))
    indptr = np.concatenate([[0], np.cumsum(counts)])
    indices, data = kernel_rows(*args, counts, indptr)
    return csr_matrix((data, indices, indptr), shape=(len(pts), len(pts)))


def fit_gaussian_field(
    points: np.ndarray,
    sigma: float = 0.01,
    regularization: float = 1e-3,
    cutoff: float = 4.0,
    tol: float = 1e-6,
    max_iter: int = 2000,
) -> GaussianField:
    """Fit ``alpha = (K + lambda I)^-1 t`` with t = 1 on inducing points.

    Args:
        points: (M, 3) inducing points in m (see :func:`voxel_means`).
        sigma: kernel width in m (thesis: 0.01).
        regularization: lambda of each point relative to its row sum of K (a diagonal
            lambda), so the fitted value at the data, about ``1 / (1 + regularization)``,
            does not depend on the point density; it must stay well below ``1 / tau - 1``.
        cutoff: where the kernel's taper reaches 0, in units of sigma.
        tol: relative residual at which conjugate gradients stop.
        max_iter: iteration limit of conjugate gradients.

    Returns:
        The fitted field.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    K = kernel_matrix(pts, sigma, cutoff)
    # lambda_i scales with the kernel's row sum, i.e. the local density of the inducing
    # points: with one global lambda, sparse parts (a single-layer floor) are fitted far
    # below t = 1 while dense ones are not, and the tau-surface breaks up there.
    lam = regularization * np.asarray(K.sum(axis=1)).ravel()
    A = K + diags(lam, format="csr")
    iterations = 0

    def count(_: np.ndarray) -> None:
        nonlocal iterations
        iterations += 1

    alpha, info = cg(A, np.ones(len(pts)), rtol=tol, maxiter=max_iter, callback=count)
    if info > 0:
        raise RuntimeError(f"conjugate gradients did not converge in {max_iter} iterations")
    return GaussianField(
        centres=pts, alpha=alpha, sigma=sigma, cutoff=cutoff, cg_iterations=iterations
    )
