"""Where new fluid goes: a block of particles, or a container filled to a volume.

Particles are placed on a cubic lattice at the fluid's rest spacing, which the position-based
fluid treats as exactly at rest density, so a spawned fluid neither jumps nor sags.
"""

from __future__ import annotations

import numpy as np

from pour_gym.errors import InputError
from pour_gym.features import ContainerGeometry
from pour_gym.fluid.sdf import SignedDistanceField


def block(low: np.ndarray, high: np.ndarray, spacing: float) -> np.ndarray:
    """Lattice points filling the box ``[low, high]``.

    Args:
        low: (3,) lower corner, m.
        high: (3,) upper corner, m.
        spacing: lattice spacing, m.

    Returns:
        (N, 3) positions, m, each at least half a spacing inside the box.

    Raises:
        InputError: the box is too small to hold one particle.
    """
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    axes = [
        np.arange(lo + spacing / 2, hi - spacing / 2 + 1e-12, spacing)
        for lo, hi in zip(low, high, strict=True)
    ]
    if any(len(a) == 0 for a in axes):
        raise InputError(
            f"a block from {low.tolist()} to {high.tolist()} holds no particle of spacing "
            f"{spacing} m; make it at least one spacing wide in each direction"
        )
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def fill_lattice(
    geometry: ContainerGeometry,
    sdf: SignedDistanceField,
    spacing: float,
    count: int,
    lattice: np.ndarray | None = None,
) -> np.ndarray:
    """The ``count`` lowest lattice points in an upright container's cavity, in its frame.

    Args:
        geometry: the container's geometry (its cavity voxels).
        sdf: the container's signed-distance field.
        spacing: lattice spacing, m.
        count: particles wanted.
        lattice: :func:`cavity_lattice` of the same arguments, if already computed.

    Returns:
        (count, 3) positions in the container's frame, m.

    Raises:
        InputError: the cavity holds fewer than ``count`` lattice points.
    """
    candidates = cavity_lattice(geometry, sdf, spacing) if lattice is None else lattice
    if len(candidates) < count:
        raise InputError(
            f"the container holds {len(candidates)} particles of spacing {spacing} m below its "
            f"rim; {count} were asked for (lower the fill or the spacing)"
        )
    return candidates[:count]


def cavity_lattice(
    geometry: ContainerGeometry, sdf: SignedDistanceField, spacing: float
) -> np.ndarray:
    """All lattice points of an upright container's cavity, lowest first, in its frame.

    A point qualifies when it lies in the cavity voxels and at least about half a spacing
    from the container's material, so that no particle starts in a wall.

    Args:
        geometry: the container's geometry (its cavity voxels).
        sdf: the container's signed-distance field.
        spacing: lattice spacing, m.

    Returns:
        (M, 3) positions, layer by layer from the bottom; a partial top layer fills from
        the axis outwards.
    """
    cav = geometry.cavity
    lo = cav.origin
    hi = cav.origin + cav.voxel * (np.array(cav.mask.shape) - 1)
    # Columns placed symmetrically about the rim's axis keep a fill level and centred; the
    # first layer rests on the cavity's floor.
    floor = cav.origin[2] + cav.voxel * (np.argmax(cav.mask.any(axis=(0, 1))) - 0.5)
    axes = []
    for a in range(3):
        centre = geometry.rim_center[a] if a < 2 else floor
        k0 = np.floor((lo[a] - centre) / spacing) - 1
        k1 = np.ceil((hi[a] - centre) / spacing) + 1
        axes.append(centre + spacing * (np.arange(k0, k1) + 0.5))
    candidates = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    inside = cav.contains(candidates)
    candidates = candidates[inside]
    d, _ = sdf.sample(candidates)
    candidates = candidates[d >= 0.45 * spacing]
    # Layer by layer from the bottom; a partial top layer fills from the axis outwards.
    radial = np.round(np.hypot(*(candidates[:, :2] - geometry.rim_center[:2]).T) / spacing, 6)
    order = np.lexsort((candidates[:, 1], candidates[:, 0], radial, candidates[:, 2]))
    return candidates[order]
