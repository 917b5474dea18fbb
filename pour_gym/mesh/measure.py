"""Geometry of an upright container measured from its mesh alone (no part labels).

These measures let the reconstruction report compare any mesh with ground truth:

- rim: in each azimuth wedge, the vertices in a thin band below the wedge's top; their
  mean is the rim centre and their mean distance to it the rim radius (the thesis's
  definition, 5.1, with the top band standing in for the rim label);
- height: the mean of the wedges' tops above the lowest vertex (the top of the lip above
  the base);
- holding volume: how much water the mesh holds before it overflows, found by voxelising the
  solid and flooding it (a voxel holds water when the empty region below the water level that
  contains it does not reach the sides or the bottom of the grid);
- Chamfer distance between two surfaces.

Units are metres and m^3; z is up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.errors import InputError
from pour_gym.io.open3d_loader import open3d

if TYPE_CHECKING:
    import trimesh


@dataclass(frozen=True)
class ContainerDimensions:
    """Dimensions of an upright container.

    Attributes:
        height: the rim's top above the mesh's lowest point, in m.
        rim_radius: mean distance of the rim band's vertices to their centre, in m.
        rim_center: (3,) centre of the top band, in m.
        volume: holding volume up to the overflow level, in m^3.
        closed: why the container looks closed (:func:`opening_problem`), None if open.
    """

    height: float
    rim_radius: float
    rim_center: tuple[float, float, float]
    volume: float
    closed: str | None = None


def top_band_rim(
    vertices: np.ndarray, band: float = 0.002, sectors: int = 36
) -> tuple[np.ndarray, float, float]:
    """Rim centre, rim radius and rim height from the top band of each azimuth sector.

    The vertices are split into ``sectors`` wedges about the vertical axis through the
    centre of the top tenth of the mesh; in each wedge the vertices within ``band`` of that
    wedge's highest vertex form the rim. Taking the band per wedge, not globally, keeps a
    single bump (scan noise) or a tilted rim from shrinking the rim to one side.

    Args:
        vertices: (V, 3) positions in m of an upright container.
        band: thickness of the band below each wedge's top, in m.
        sectors: number of wedges.

    Returns:
        The rim centre (3,), the mean distance of the rim vertices to it (the rim radius)
        and the mean of the wedges' top heights, all in m.
    """
    v = np.asarray(vertices, dtype=float)
    mask, top = rim_band_mask(v, band, sectors)
    rim = v[mask]
    centre = rim.mean(axis=0)
    radius = float(np.linalg.norm(rim - centre, axis=1).mean())
    return centre, radius, top


def azimuth_wedges(
    points: np.ndarray, wedges: int, axis: np.ndarray | tuple[float, float] = (0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth of each point about a vertical axis, and the wedge it falls in.

    Args:
        points: (N, 3) positions, z up.
        wedges: number of equal wedges from -pi to pi.
        axis: (x, y) of the vertical axis.

    Returns:
        ``(azimuth, wedge)``: (N,) angles in rad and (N,) wedge indices.
    """
    azimuth = np.arctan2(points[:, 1] - axis[1], points[:, 0] - axis[0])
    wedge = np.minimum(((azimuth + np.pi) / (2 * np.pi) * wedges).astype(int), wedges - 1)
    return azimuth, wedge


def max_per_group(groups: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """The largest value in each of ``n`` groups (-inf for an empty group)."""
    out = np.full(n, -np.inf)
    np.maximum.at(out, groups, values)
    return out


def rim_band_mask(
    vertices: np.ndarray, band: float = 0.002, sectors: int = 36
) -> tuple[np.ndarray, float]:
    """Which vertices form the rim band of :func:`top_band_rim`, and the mean wedge top.

    Args:
        vertices: (V, 3) positions in m, z up.
        band: thickness of the band below each wedge's top, in m.
        sectors: number of wedges about the axis through the top tenth's centre.

    Returns:
        A boolean mask over the vertices and the mean of the wedges' top heights in m.
    """
    v = np.asarray(vertices, dtype=float)
    upper = v[v[:, 2] >= np.percentile(v[:, 2], 90)]
    _, wedge = azimuth_wedges(v, sectors, upper[:, :2].mean(axis=0))
    top = max_per_group(wedge, v[:, 2], sectors)
    # On a coarse mesh a wedge may hold no rim vertex at all; its top is then something
    # lower (a handle), a dip against both neighbouring wedges, and it is left out.
    dip = 0.1 * float(np.ptp(v[:, 2]))
    neighbours = np.minimum(np.roll(top, 1), np.roll(top, -1))
    valid = np.isfinite(top) & ~(top < neighbours - dip)
    mask = valid[wedge] & (v[:, 2] >= top[wedge] - band)
    return mask, float(top[valid].mean())


# Sub-micrometre offsets of the vertical rays off the voxel columns' centres, m: the first
# that gives a column an even number of crossings is used.
RAY_OFFSETS = ((1.234567e-7, 2.345678e-7), (3.1e-7, -1.7e-7), (-2.3e-7, 4.1e-7), (4.7e-7, 3.3e-7))


def _column_crossings(
    scene, x: np.ndarray, y: np.ndarray, z0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where upward rays from (x, y, z0) cross a surface.

    Hits on the shared edge of two triangles come twice at the same depth: kept once.

    Returns:
        ``(counts, splits, t)``: crossings per ray, offsets of each ray's run in ``t``, and
        the heights above ``z0`` (m), sorted within each ray.
    """
    rays = np.zeros((len(x), 6), dtype=np.float32)
    rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = x, y, z0, 1.0
    hits = scene.list_intersections(open3d().core.Tensor(rays))
    splits = hits["ray_splits"].numpy().astype(np.int64)
    t_hit = hits["t_hit"].numpy().astype(np.float64)
    ray_of_hit = np.repeat(np.arange(len(rays)), np.diff(splits))
    order = np.lexsort((t_hit, ray_of_hit))
    t_hit, ray_of_hit = t_hit[order], ray_of_hit[order]
    dup = np.zeros(len(t_hit), dtype=bool)
    dup[1:] = (ray_of_hit[1:] == ray_of_hit[:-1]) & (np.diff(t_hit) < 1e-7)
    t_hit, ray_of_hit = t_hit[~dup], ray_of_hit[~dup]
    counts = np.bincount(ray_of_hit, minlength=len(rays))
    return counts, np.concatenate([[0], np.cumsum(counts)]), t_hit


def occupancy_grid(
    mesh: trimesh.Trimesh, voxel: float, pad: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Voxelise a closed mesh by ray parity along vertical columns.

    One ray per (x, y) column is cast upward through the mesh; a voxel is solid when its
    centre lies between an odd and the following even crossing.

    Args:
        mesh: a closed (watertight) mesh, in m.
        voxel: edge length of the voxels, in m.
        pad: empty voxels added on every side, so that the outside is connected.

    Returns:
        ``(occupied, origin)``: a boolean (nx, ny, nz) array and the centre of voxel
        (0, 0, 0) in m.

    Raises:
        InputError: more than 1 % of the columns cross the surface an odd number of times
            at every offset tried (the mesh has holes).
    """
    o3d = open3d()
    lo, hi = mesh.bounds
    origin = lo - (pad - 0.5) * voxel
    shape = np.ceil((hi - lo) / voxel).astype(int) + 2 * pad
    xs = origin[0] + voxel * np.arange(shape[0])
    ys = origin[1] + voxel * np.arange(shape[1])
    gx, gy = (g.ravel() for g in np.meshgrid(xs, ys, indexing="ij"))
    z0 = origin[2] - voxel
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)),
    )
    # A column that runs exactly along a mesh edge or through a vertex may be counted by
    # both triangles or by neither (float32 ray casting differs between CPUs here); an
    # offset far below the voxel keeps columns off the (often axis-aligned) edges, and a
    # column with an odd count is cast again at other offsets before it is given up.
    zc = origin[2] + voxel * np.arange(shape[2]) - z0  # voxel centres as ray parameters
    occupied = np.zeros(shape, dtype=bool)
    flat = occupied.reshape(-1, shape[2])
    todo = np.arange(len(gx))
    for dx, dy in RAY_OFFSETS:
        counts, splits, t = _column_crossings(scene, gx[todo] + dx, gy[todo] + dy, z0)
        even = counts % 2 == 0
        for k in np.flatnonzero(even & (counts >= 2)):
            flat[todo[k]] = np.searchsorted(t[splits[k] : splits[k + 1]], zc) % 2 == 1
        todo = todo[~even]
        if len(todo) == 0:
            break
    if len(todo) > 0.01 * len(gx):
        raise InputError(
            f"the mesh is not closed: {len(todo) / len(gx):.1%} of vertical rays cross its "
            "surface an odd number of times; repair it (e.g. trimesh.repair.fill_holes) or "
            "pass a watertight mesh"
        )
    unread = np.zeros(shape[:2], dtype=bool)
    unread.flat[todo] = True
    # A column no offset could read (a hole in the mesh) takes a neighbour's: left empty,
    # it would be a shaft through the wall that the water escapes by.
    for ray in todo:
        i, j = divmod(int(ray), shape[1])
        for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            ni, nj = i + di, j + dj
            if 0 <= ni < shape[0] and 0 <= nj < shape[1] and not unread[ni, nj]:
                occupied[i, j] = occupied[ni, nj]
                break
    return occupied, origin


def shell_occupancy(
    mesh: trimesh.Trimesh, voxel: float, pad: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Voxelise a surface that may have holes: the voxels its surface passes through.

    Points are drawn on the surface at a spacing well below the voxel, their voxels are
    marked and the marks dilated by one voxel, which closes holes up to about two voxels
    wide. Empty space the shell encloses completely (the inside of a closed wall) is filled.

    Args:
        mesh: any triangle mesh, in m.
        voxel: voxel edge, in m.
        pad: empty voxels added on every side.

    Returns:
        ``(occupied, origin)`` as :func:`occupancy_grid`.
    """
    return shell_occupancy_from_points(surface_samples(mesh, 0.4 * voxel), voxel, pad)


def surface_samples(mesh: trimesh.Trimesh, spacing: float, seed: int = 0) -> np.ndarray:
    """Random points on the surface, about one per ``spacing``^2 of area, plus the vertices."""
    count = int(np.ceil(mesh.area / spacing**2))
    import trimesh

    points, _ = trimesh.sample.sample_surface(mesh, count, seed=seed)
    return np.concatenate([points, np.asarray(mesh.vertices)])


def shell_occupancy_from_points(
    points: np.ndarray, voxel: float, pad: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Voxels touched by dense surface points, dilated once, enclosed space filled.

    Args:
        points: (N, 3) points on a surface, spaced well below ``voxel``, in m.
        voxel: voxel edge, in m.
        pad: empty voxels added on every side.

    Returns:
        ``(occupied, origin)`` as :func:`occupancy_grid`.
    """
    lo, hi = points.min(axis=0), points.max(axis=0)
    origin = lo - pad * voxel
    shape = np.ceil((hi - lo) / voxel).astype(int) + 2 * pad + 1
    idx = np.clip(np.round((points - origin) / voxel).astype(int), 0, shape - 1)
    occupied = np.zeros(shape, dtype=bool)
    occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    # Empty space enclosed by the shell is the inside of a closed wall, not a cavity.
    from scipy import ndimage

    return ndimage.binary_fill_holes(ndimage.binary_dilation(occupied)), origin


def _holds_water(
    empty: np.ndarray, seed: tuple[int, int, int], level: int
) -> tuple[bool, np.ndarray | None]:
    """Whether the seed's empty region below ``level`` is enclosed, and that region."""
    region = empty[:, :, :level]
    from scipy import ndimage

    labels, _ = ndimage.label(region)
    own = labels[seed]
    if own == 0:
        return False, None
    sides = (labels[0], labels[-1], labels[:, 0], labels[:, -1], labels[:, :, 0])
    if any(np.any(face == own) for face in sides):
        return False, None
    return True, labels == own


@dataclass
class Cavity:
    """The water a container holds, as voxels.

    Attributes:
        mask: boolean (nx, ny, nz) voxels of water, in the grid of the occupancy.
        origin: centre of voxel (0, 0, 0), in m.
        voxel: voxel edge, in m.
        level: height of the water surface (top of the highest water layer), in m.
        overflows: raising the level far enough lets the water out over a rim (False for
            a container whose opening is closed: its inside is sealed at every level).
    """

    mask: np.ndarray
    origin: np.ndarray
    voxel: float
    level: float
    overflows: bool = True

    @property
    def volume(self) -> float:
        """Volume of the water, in m^3."""
        return float(np.count_nonzero(self.mask)) * self.voxel**3

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether each of the (N, 3) points lies in a water voxel (same frame as the grid)."""
        idx = np.round((np.asarray(points) - self.origin) / self.voxel).astype(int)
        inside = np.all((idx >= 0) & (idx < np.array(self.mask.shape)), axis=1)
        out = np.zeros(len(idx), dtype=bool)
        i = idx[inside]
        out[inside] = self.mask[i[:, 0], i[:, 1], i[:, 2]]
        return out


def cavity_from_grid(
    occupied: np.ndarray, origin: np.ndarray, voxel: float, seed_xy: tuple[int, int]
) -> Cavity:
    """The water an upright voxelised container holds.

    The water is seeded in the first empty voxel above the base in column ``seed_xy`` (the
    rim centre's column) and the level is raised, by bisection over voxel layers, to the
    highest one at which that water is still enclosed.

    Args:
        occupied: boolean (nx, ny, nz) solid voxels, z up.
        origin: centre of voxel (0, 0, 0), in m.
        voxel: voxel edge in m.
        seed_xy: (i, j) column index through the opening.

    Returns:
        The cavity; empty when the column has no floor or the region never closes.
    """
    nothing = Cavity(np.zeros(occupied.shape, dtype=bool), origin, voxel, float(origin[2]))
    column = occupied[seed_xy[0], seed_xy[1]]
    solid = np.flatnonzero(column)
    if len(solid) == 0:
        return nothing
    # The first empty voxel above the lowest solid run is the bottom of the cavity.
    k = solid[0]
    while k < len(column) and column[k]:
        k += 1
    if k >= len(column) - 1:
        return nothing
    empty = ~occupied
    seed = (seed_xy[0], seed_xy[1], k)
    lo, hi = k + 1, occupied.shape[2]  # holds at lo (one layer of water), find the last
    ok, water = _holds_water(empty, seed, lo)
    if not ok:
        return nothing
    sealed, region = _holds_water(empty, seed, hi)
    if sealed:  # no level lets it out: the opening is closed (a cap over the rim)
        return Cavity(region, origin, voxel, float(origin[2] + (hi - 0.5) * voxel), False)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        holds, region = _holds_water(empty, seed, mid)
        if holds:
            lo, water = mid, region
        else:
            hi = mid
    mask = np.zeros(occupied.shape, dtype=bool)
    mask[:, :, :lo] = water
    return Cavity(mask, origin, voxel, float(origin[2] + (lo - 0.5) * voxel))


def cavity(mesh: trimesh.Trimesh, voxel: float = 5e-4, closed: bool = True) -> Cavity:
    """The water an upright mesh holds before it overflows, as voxels in the mesh's frame.

    Args:
        mesh: the container, upright (z up), in m.
        voxel: voxel edge in m.
        closed: voxelise the solid by ray parity (watertight meshes); with ``False`` the
            surface is voxelised as a thin shell (for scans with holes).

    Returns:
        The cavity.
    """
    occupied, origin = (occupancy_grid if closed else shell_occupancy)(mesh, voxel)
    return _cavity_below_rim(occupied, origin, voxel, np.asarray(mesh.vertices))


def _cavity_below_rim(
    occupied: np.ndarray, origin: np.ndarray, voxel: float, points: np.ndarray
) -> Cavity:
    """The cavity seeded in the column through the rim centre of ``points``."""
    centre, _, _ = top_band_rim(points)
    ij = np.round((centre[:2] - origin[:2]) / voxel).astype(int)
    ij = np.clip(ij, 0, np.array(occupied.shape[:2]) - 1)
    return cavity_from_grid(occupied, origin, voxel, (int(ij[0]), int(ij[1])))


# An open container holds a good part of its outer volume; a sealed scan turned upside down
# "holds" only the dent in its base (the YCB pitcher: 5 ml of 2 litres).
MIN_CAVITY_SHARE = 0.05


def opening_problem(water: Cavity, hull: float) -> str | None:
    """Why an upright container looks closed (no opening at its top), or None if it is open.

    Two signs: the water never overflows however high it stands (the inside is sealed),
    or the cavity is a tiny share of the mesh's convex hull (the search for "up" found a
    dent in the outside of a sealed body, not the inside).

    Args:
        water: the container's cavity, upright.
        hull: the volume of the container's convex hull, in m^3.

    Returns:
        A sentence naming the problem, or None.
    """
    if not water.overflows:
        return (
            f"its inside ({water.volume * 1e6:.0f} ml) is sealed: water poured in could "
            "never run out over a rim"
        )
    if water.volume < MIN_CAVITY_SHARE * hull:
        return (
            f"its only cavity holds {water.volume * 1e6:.1f} ml, "
            f"{water.volume / hull:.1%} of its {hull * 1e6:.0f} ml outer volume"
        )
    return None


def shell_holding_volume(points: np.ndarray, voxel: float) -> float:
    """Holding volume in m^3 of an upright surface given as dense points on it."""
    occupied, origin = shell_occupancy_from_points(points, voxel)
    return _cavity_below_rim(occupied, origin, voxel, points).volume


def holding_volume(mesh: trimesh.Trimesh, voxel: float = 5e-4, closed: bool = True) -> float:
    """How much water an upright mesh holds before it overflows, in m^3.

    Args:
        mesh: the container, upright (z up), in m.
        voxel: voxel edge in m; the result is within about one voxel layer of water.
        closed: the mesh is watertight and its solid is voxelised by ray parity; with
            ``False`` its surface is voxelised as a thin shell instead (for scans with
            holes), which holds slightly less than the real cavity.

    Returns:
        The holding volume in m^3.
    """
    return cavity(mesh, voxel, closed).volume


def container_dimensions(mesh: trimesh.Trimesh, voxel: float = 5e-4) -> ContainerDimensions:
    """Height, rim and holding volume of an upright container mesh.

    Args:
        mesh: a watertight mesh, upright, in m.
        voxel: voxel edge for the volume, in m.

    Returns:
        The dimensions.
    """
    v = np.asarray(mesh.vertices)
    centre, radius, top = top_band_rim(v)
    water = cavity(mesh, voxel)
    return ContainerDimensions(
        height=top - float(v[:, 2].min()),
        rim_radius=radius,
        rim_center=(float(centre[0]), float(centre[1]), float(centre[2])),
        volume=water.volume,
        closed=opening_problem(water, float(mesh.convex_hull.volume)),
    )


def _distance_to(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Exact distance from each point to the nearest point of the mesh's surface, in m."""
    o3d = open3d()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)),
    )
    return scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()


def chamfer_distance(
    a: trimesh.Trimesh, b: trimesh.Trimesh, samples: int = 20000, seed: int = 0
) -> float:
    """Symmetric Chamfer distance between two surfaces, in m.

    The mean of the two directed means of the distance from points drawn uniformly on one
    surface to the other surface (exact point-to-triangle distances, so the figure does not
    depend on the sampling density).

    Args:
        a: first mesh.
        b: second mesh.
        samples: points drawn on each surface.
        seed: sampling seed.

    Returns:
        The distance in m.
    """
    import trimesh

    pa, _ = trimesh.sample.sample_surface(a, samples, seed=seed)
    pb, _ = trimesh.sample.sample_surface(b, samples, seed=seed + 1)
    return float(0.5 * (_distance_to(b, pa).mean() + _distance_to(a, pb).mean()))
