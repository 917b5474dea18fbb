"""Bookkeeping of the fluid: which container each particle is in.

A particle is in container k when its centre lies in k's cavity (the water the container
holds below its rim, as voxels in the container's frame), not merely in its bounding box;
a particle in no cavity is elsewhere (in flight, or spilled on the table).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np

from pour_gym.features import ContainerGeometry


@dataclass(frozen=True)
class Census:
    """Where every particle is.

    Attributes:
        where: (N,) index of the container each particle is in, -1 for elsewhere.
        counts: (K,) particles in each container.
        elsewhere: particles in no container.
    """

    where: np.ndarray
    counts: np.ndarray
    elsewhere: int

    @property
    def total(self) -> int:
        """All particles (the counts and elsewhere add up to it)."""
        return int(self.counts.sum()) + self.elsewhere


def take_census(
    points: np.ndarray,
    geometries: Sequence[ContainerGeometry],
    poses: Sequence[tuple[np.ndarray, np.ndarray]],
) -> Census:
    """Assign every particle to the container whose cavity holds it, or to elsewhere.

    Args:
        points: (N, 3) particle positions in the world, m.
        geometries: each container's geometry.
        poses: each container's ``(rotation (3, 3), translation (3,))``.

    Returns:
        The census. Cavities of distinct containers do not overlap (their walls keep them
        apart); should two claim a particle, the first container listed takes it.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    where = np.full(len(points), -1, dtype=np.int64)
    for k in range(len(geometries) - 1, -1, -1):
        rot, trans = poses[k]
        cavity = geometries[k].cavity
        _mark_inside(points, np.ascontiguousarray(rot, dtype=np.float64),
                     np.ascontiguousarray(trans, dtype=np.float64), cavity.mask,
                     np.ascontiguousarray(cavity.origin, dtype=np.float64), float(cavity.voxel),
                     k, where)  # fmt: skip
    counts = np.bincount(where[where >= 0], minlength=len(geometries)).astype(np.int64)
    return Census(where=where, counts=counts, elsewhere=int(np.count_nonzero(where < 0)))


@nb.njit(cache=True)
def _mark_inside(points, rotation, translation, mask, origin, voxel, k, where):
    """Set ``where[i] = k`` for every point in a water voxel of container k's cavity.

    The points are taken into the container's frame and rounded to the nearest voxel, as
    :meth:`pour_gym.mesh.measure.Cavity.contains` does, in one loop: the census runs every
    step, on every particle, for every container.
    """
    nx, ny, nz = mask.shape
    for i in range(points.shape[0]):
        dx = points[i, 0] - translation[0]
        dy = points[i, 1] - translation[1]
        dz = points[i, 2] - translation[2]
        ix = int(
            np.round(
                (dx * rotation[0, 0] + dy * rotation[1, 0] + dz * rotation[2, 0] - origin[0])
                / voxel
            )
        )
        iy = int(
            np.round(
                (dx * rotation[0, 1] + dy * rotation[1, 1] + dz * rotation[2, 1] - origin[1])
                / voxel
            )
        )
        iz = int(np.round((dx * rotation[0, 2] + dy * rotation[1, 2] + dz * rotation[2, 2]
                           - origin[2]) / voxel))  # fmt: skip
        if 0 <= ix < nx and 0 <= iy < ny and 0 <= iz < nz and mask[ix, iy, iz]:
            where[i] = k
