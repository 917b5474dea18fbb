"""Bookkeeping of the fluid: which container each particle is in.

A particle is in container k when its centre lies in k's cavity (the water the container
holds below its rim, as voxels in the container's frame), not merely in its bounding box;
a particle in no cavity is elsewhere (in flight, or spilled on the table).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pour_gym.features import ContainerGeometry, inside_container


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
    where = np.full(len(points), -1, dtype=np.int64)
    for k in range(len(geometries) - 1, -1, -1):
        rot, trans = poses[k]
        where[inside_container(geometries[k], points, rot, trans)] = k
    counts = np.bincount(where[where >= 0], minlength=len(geometries)).astype(np.int64)
    return Census(where=where, counts=counts, elsewhere=int(np.count_nonzero(where < 0)))
