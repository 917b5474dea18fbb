"""High-level features of chapter 5.1, computed from a labelled mesh.

Container geometry (in the mesh's own frame, upright):

- rim centre: mean of the rim vertices; rim radius: their mean distance to it;
- height: the rim centre above the lowest vertex;
- lip point: the lowest rim vertex in the container's current pose;
- container volume: the convex hull of the container (inner-surface) vertices, as in the
  thesis, and, better, the cavity: the water the mesh holds below its rim (a flood fill).

Features of fluid particles for a container in a pose ``(R, t)`` (world = R @ local + t),
vectorised over particles:

- f1 relative distance: horizontal distance of a particle to the rim centre / rim radius;
- f2 relative height: height of a particle above the rim centre / height;
- f3 fluid volume: fluid volume in the container / container volume;
- f4 fluid volume above the lip: fluid volume in the container above the lip point (the
  lowest rim vertex in the container's current pose) / container volume.

The environments compute their observations with these functions: one definition of each.

Fluid volume comes either from the particle count (incompressible fluid: N times the volume
per particle) or from the local density of thesis 5.2, ``rho(p) = sum_n [|p - p_n| <
3 sigma] N(|p - p_n|; 0, sigma)`` and ``V = sum_p 1 / rho(p)``. On a resting fluid on a
cubic lattice the two agree within 5 % when sigma is half the particle spacing
(tested); with larger sigma the density estimate overstates the volume, because particles
near a free surface or a wall see fewer neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.errors import InputError
from pour_gym.io.cache import cache_dir, mesh_key, write_npz
from pour_gym.mesh.measure import Cavity, cavity
from pour_gym.parts import Part

if TYPE_CHECKING:
    from collections.abc import Callable

    import trimesh


@dataclass
class ContainerGeometry:
    """Geometry of a labelled container in its own upright frame (m, m^3).

    Attributes:
        rim_center: (3,) mean of the rim vertices.
        rim_radius: mean distance of the rim vertices to the rim centre.
        height: rim centre above the lowest vertex.
        lip_point: (3,) lowest rim vertex when upright.
        container_volume: convex hull of the container vertices (thesis 5.1).
        cavity_volume: water held below the rim (flood fill of the mesh).
        rim_vertices: (R, 3) rim vertices, for the lip point in other poses.
        cavity: the cavity voxels, for testing whether particles are inside.
    """

    rim_center: np.ndarray
    rim_radius: float
    height: float
    lip_point: np.ndarray
    container_volume: float
    cavity_volume: float
    rim_vertices: np.ndarray
    cavity: Cavity

    def to_dict(self) -> dict:
        """The scalar geometry as a JSON-serialisable dict."""
        return {
            "rim_center": self.rim_center.tolist(),
            "rim_radius": self.rim_radius,
            "height": self.height,
            "lip_point": self.lip_point.tolist(),
            "container_volume": self.container_volume,
            "cavity_volume": self.cavity_volume,
        }


CAVITY_VOXEL = 7.5e-4  # m: a tenth of a millilitre of resolution at cup scale


CAVITY_VERSION = 1  # bumped when the way cavities are computed changes (cached ones go stale)


def container_cavity(
    mesh: trimesh.Trimesh, voxel: float = CAVITY_VOXEL, cache: bool = True
) -> Cavity:
    """The water an upright container mesh holds (watertight or not), as voxels.

    A single watertight body is voxelised by ray parity; any other mesh (holes, or bodies
    that overlap, where parity counts a point inside two of them as outside) as a shell.
    The result is kept in the cache folder (:func:`pour_gym.io.cache.cache_dir`), keyed by
    the mesh and the voxel: every environment's reset loads its containers, and computing
    a cavity takes about a second.

    Args:
        mesh: the container, upright, in m.
        voxel: voxel edge, in m.
        cache: read and write the cache.
    """
    closed = bool(mesh.is_watertight) and mesh.body_count == 1
    path = None
    if cache:
        key = mesh_key(mesh, voxel, float(closed), CAVITY_VERSION)
        path = cache_dir("cavity") / f"cavity_{key}.npz"
        if path.is_file():
            with np.load(path) as data:
                return cavity_from_arrays(data)
    water = cavity(mesh, voxel, closed=closed)
    if path is not None:
        write_npz(path, **cavity_arrays(water))
    return water


def cavity_arrays(water: Cavity, prefix: str = "") -> dict[str, np.ndarray]:
    """A cavity as arrays for an ``.npz`` (its voxels packed to bits), keys ``prefix + name``."""
    arrays = {
        "bits": np.packbits(water.mask), "shape": np.array(water.mask.shape),
        "origin": water.origin, "voxel": water.voxel, "level": water.level,
        "overflows": water.overflows,
    }  # fmt: skip
    return {prefix + k: np.asarray(v) for k, v in arrays.items()}


def cavity_from_arrays(data, prefix: str = "") -> Cavity:
    """The cavity :func:`cavity_arrays` wrote (``data``: a loaded ``.npz`` or a dict)."""
    shape = tuple(int(n) for n in data[prefix + "shape"])
    mask = np.unpackbits(data[prefix + "bits"], count=int(np.prod(shape))).reshape(shape)
    return Cavity(
        mask.astype(bool), data[prefix + "origin"], float(data[prefix + "voxel"]),
        float(data[prefix + "level"]), bool(data[prefix + "overflows"]),
    )  # fmt: skip


def container_geometry(
    mesh: trimesh.Trimesh,
    labels: np.ndarray,
    voxel: float = CAVITY_VOXEL,
    water: Cavity | None = None,
) -> ContainerGeometry:
    """Geometry of an upright labelled container.

    Args:
        mesh: the container, upright, in m (watertight or not).
        labels: (V,) part of each vertex.
        voxel: voxel edge for the cavity, in m.
        water: :func:`container_cavity` of the mesh, if already computed.

    Returns:
        The geometry.

    Raises:
        InputError: labels of the wrong length, or no rim or container vertices.
    """
    v = np.asarray(mesh.vertices, dtype=float)
    labels = np.asarray(labels)
    if labels.shape != (len(v),):
        raise InputError(f"{len(labels)} labels for {len(v)} vertices")
    rim = v[labels == Part.RIM]
    inner = v[labels == Part.CONTAINER]
    if len(rim) < 3 or len(inner) < 4:
        raise InputError(
            f"the labels have {len(rim)} rim and {len(inner)} container vertices (at least 3 "
            "and 4 needed): label the mesh with pour-gym label, and check that it is an open "
            "container"
        )
    # Imported here: an environment loads its containers' geometry from the cache and
    # never needs Qhull (scipy.spatial weighs some 25 MB per process).
    from scipy.spatial import ConvexHull, QhullError

    centre = rim.mean(axis=0)
    try:
        hull = float(ConvexHull(inner).volume)
    except QhullError:
        hull = 0.0
    if water is None:
        water = container_cavity(mesh, voxel)
    return ContainerGeometry(
        rim_center=centre,
        rim_radius=float(np.linalg.norm(rim - centre, axis=1).mean()),
        height=float(centre[2] - v[:, 2].min()),
        lip_point=rim[np.argmin(rim[:, 2])],
        container_volume=hull,
        cavity_volume=water.volume,
        rim_vertices=rim,
        cavity=water,
    )


def lip_point(geometry: ContainerGeometry, rotation: np.ndarray, translation: np.ndarray):
    """The lowest rim vertex, in world coordinates, of the container in a pose.

    Args:
        geometry: the container's geometry.
        rotation: (3, 3) rotation of the container (world = R @ local + t).
        translation: (3,) position of the container's frame origin, in m.

    Returns:
        (3,) world position in m.
    """
    world = geometry.rim_vertices @ np.asarray(rotation).T + translation
    return world[np.argmin(world[:, 2])]


def inside_container(
    geometry: ContainerGeometry, points: np.ndarray, rotation: np.ndarray, translation: np.ndarray
) -> np.ndarray:
    """Whether world points lie in the container's cavity (by its voxels, not a box)."""
    local = (np.asarray(points) - translation) @ np.asarray(rotation)
    return geometry.cavity.contains(local)


def relative_distance_height(
    geometry: ContainerGeometry, points: np.ndarray, rotation: np.ndarray, translation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """f1 and f2 of each particle.

    Args:
        geometry: the container's geometry.
        points: (N, 3) particle positions in the world, m.
        rotation: (3, 3) container rotation.
        translation: (3,) container position, m.

    Returns:
        ``(f1, f2)``, each (N,): horizontal distance to the rim centre over the rim radius,
        and height above the rim centre over the container's height.
    """
    c = np.asarray(rotation) @ geometry.rim_center + translation
    p = np.asarray(points, dtype=float)
    f1 = np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) / geometry.rim_radius
    f2 = (p[:, 2] - c[2]) / geometry.height
    return f1, f2


def count_volume(n_particles: int, particle_volume: float) -> float:
    """Fluid volume of an incompressible particle fluid: count times volume per particle."""
    return n_particles * particle_volume


def density_volume(points: np.ndarray, sigma: float) -> float:
    """Fluid volume from the local density of each particle (thesis 5.2), in m^3.

    Args:
        points: (N, 3) particle positions, m.
        sigma: width of the Gaussian, m (half the particle spacing agrees with the
            count on a resting fluid).

    Returns:
        ``sum_p 1 / rho(p)`` with ``rho(p)`` the Gaussian-weighted number density of the
        particles within 3 sigma (the particle itself included).
    """
    p = np.asarray(points, dtype=float)
    if len(p) == 0:
        return 0.0
    from scipy.spatial import cKDTree

    norm = 1.0 / ((2.0 * np.pi) ** 1.5 * sigma**3)
    tree = cKDTree(p)
    pairs = tree.sparse_distance_matrix(tree, 3.0 * sigma, output_type="coo_matrix")
    weights = norm * np.exp(-(pairs.data**2) / (2.0 * sigma**2))
    # The pairs include each particle with itself (distance 0): its own term is counted.
    rho = np.bincount(pairs.row, weights, minlength=len(p))
    return float(np.sum(1.0 / rho))


def fill_fraction(volume: float, geometry: ContainerGeometry) -> float:
    """Thesis f3 of a fluid volume (m^3) in a container: the volume over the container's."""
    return float(volume) / geometry.cavity_volume


def fluid_features(
    geometry: ContainerGeometry,
    points: np.ndarray,
    rotation: np.ndarray,
    translation: np.ndarray,
    particle_volume: float,
    inside: np.ndarray | None = None,
) -> tuple[float, float]:
    """f3 and f4 of a particle fluid and a container in a pose (count-based volumes).

    Args:
        geometry: the container's geometry.
        points: (N, 3) particle positions in the world, m.
        rotation: (3, 3) container rotation.
        translation: (3,) container position, m.
        particle_volume: fluid volume per particle, m^3.
        inside: which particles are in the container (from the fluid's bookkeeping);
            computed from the cavity when not given.

    Returns:
        ``(f3, f4)``: fluid volume in the container, and the part of it above the lip
        point, each over the container's cavity volume.
    """
    if inside is None:
        inside = inside_container(geometry, points, rotation, translation)
    lip_z = lip_point(geometry, rotation, translation)[2]
    n_in = int(np.count_nonzero(inside))
    n_above = int(np.count_nonzero(inside & (np.asarray(points)[:, 2] > lip_z)))
    return (
        fill_fraction(count_volume(n_in, particle_volume), geometry),
        fill_fraction(count_volume(n_above, particle_volume), geometry),
    )


def cavity_points(geometry: ContainerGeometry) -> np.ndarray:
    """Centres of the cavity's water voxels, (M, 3), in the container's frame, m."""
    cav = geometry.cavity
    return cav.origin + cav.voxel * np.argwhere(cav.mask)


def mouth_volume(
    geometry: ContainerGeometry, rotation: np.ndarray, points: np.ndarray | None = None
) -> float:
    """Water a container holds at rest when tilted, up to the lowest point of its mouth, m^3.

    The quasi-static limit of a slow tilt: water stands level and runs out once it reaches
    the lowest point of the cavity's mouth (its top layer when upright: the inner edge of
    the rim, which the water must pass; the rim's top then slopes away outwards). For a
    straight cylinder of inner radius R and depth H holding water to h, the volume exceeds
    this exactly when tan(theta) > (H - h) / R (while the water covers the bottom).
    :func:`held_volume` measures from the lowest rim vertex instead, which on a thick
    rim is its outer edge, up to a wall's thickness lower.

    Args:
        geometry: the container's geometry.
        rotation: (3, 3) container rotation (world = R @ local + t).
        points: :func:`cavity_points` of the geometry, if already computed.

    Returns:
        The volume, m^3.
    """
    cav = geometry.cavity
    pts = cavity_points(geometry) if points is None else points
    up = np.asarray(rotation)[2]
    height = pts @ up
    lip = _mouth_level(height[_mouth(geometry, pts)], up, cav.voxel)
    return float(np.count_nonzero(height < lip)) * cav.voxel**3


def _mouth(geometry: ContainerGeometry, points: np.ndarray) -> np.ndarray:
    """Which cavity voxel centres (:func:`cavity_points`) are its mouth: its top layer."""
    cav = geometry.cavity
    top = cav.origin[2] + cav.voxel * (np.flatnonzero(cav.mask.any(axis=(0, 1)))[-1])
    return points[:, 2] >= top - 0.5 * cav.voxel


def _mouth_level(mouth_heights: np.ndarray, up: np.ndarray, voxel: float) -> float:
    """The level water stands at before it runs out: the lowest mouth voxel's top, m.

    Args:
        mouth_heights: the mouth voxel centres' heights (along ``up``), m.
        up: the world's up in the container's frame.
        voxel: the voxel size, m (a centre is half a voxel below the voxel's top).
    """
    return float(mouth_heights.min()) + 0.5 * voxel * float(np.abs(up).sum())


def held_by_tilt(
    geometry: ContainerGeometry, rotation: Callable[[float], np.ndarray], max_tilt: float
) -> np.ndarray:
    """:func:`mouth_volume` at each whole degree of tilt from 0 to ``max_tilt``, m^3.

    A tilt about a horizontal axis moves a point's height as cos(tilt) times its height
    upright plus sin(tilt) times its height at 90 deg, so the cavity's voxels are binned
    once by those two (a quarter voxel a bin, at its points' mean) and each
    tilt counts bins: milliseconds a tilt where :func:`mouth_volume` takes a pass over
    the millions of voxels of a large cavity.

    Args:
        geometry: the container's geometry.
        rotation: the container's rotation (3, 3) at a tilt in degrees about a horizontal
            axis (e.g. a held source's ``SourceFrame.rotation``).
        max_tilt: the largest tilt, deg.

    Returns:
        (floor(max_tilt) + 1,) volumes, m^3.

    Raises:
        InputError: ``rotation`` does not tilt about a horizontal axis.
    """
    cav = geometry.cavity
    points = cavity_points(geometry)
    up0, up90 = np.asarray(rotation(0.0))[2], np.asarray(rotation(90.0))[2]
    if not np.allclose(np.asarray(rotation(30.0))[2], np.cos(np.pi / 6) * up0 + 0.5 * up90):
        raise InputError("held_by_tilt needs a rotation that tilts about a horizontal axis")
    s, t = points @ up0, points @ up90
    bin_size = 0.25 * cav.voxel
    i = np.floor((s - s.min()) / bin_size).astype(np.int64)
    j = np.floor((t - t.min()) / bin_size).astype(np.int64)
    _, which, counts = np.unique(
        i * (int(j.max()) + 1) + j, return_inverse=True, return_counts=True
    )
    # Each bin at its points' mean (exact where the grid's axes meet the tilt's, as held).
    bin_s = np.bincount(which, weights=s) / counts
    bin_t = np.bincount(which, weights=t) / counts
    mouth = _mouth(geometry, points)
    mouth_s, mouth_t = s[mouth], t[mouth]
    held = []
    for tilt in np.radians(np.arange(int(np.floor(max_tilt)) + 1)):
        c, n = np.cos(tilt), np.sin(tilt)
        up = c * up0 + n * up90
        lip = _mouth_level(c * mouth_s + n * mouth_t, up, cav.voxel)
        held.append(counts[c * bin_s + n * bin_t < lip].sum())
    return np.asarray(held, dtype=np.float64) * cav.voxel**3


def held_volume(
    geometry: ContainerGeometry,
    rotation: np.ndarray,
    points: np.ndarray | None = None,
    sill: float | np.ndarray = 0.0,
) -> float | np.ndarray:
    """Water a container holds at rest when tilted: its cavity below the lip, m^3.

    In the quasi-static limit (a slow tilt) water fills the container up to a level
    surface and runs over the lowest rim point: a fill pours at a rotation exactly when its
    volume exceeds this. For a cylinder of radius R and depth H this is
    ``pi R^2 (H - R tan(theta))`` while the water still covers the bottom.

    Args:
        geometry: the container's geometry.
        rotation: (3, 3) container rotation (world = R @ local + t).
        points: :func:`cavity_points` of the geometry, if already computed.
        sill: how far the level must stand above the lowest rim point before water runs
            over, m (0 for a continuum; about 1.7 particle diameters for the particle
            fluid, whose surface particles must clear the rim's crest); an array gives
            the volume for each sill at the cost of one sort.

    Returns:
        The volume, m^3 (an array of them for an array of sills).
    """
    pts = cavity_points(geometry) if points is None else points
    up = np.asarray(rotation)[2]  # world height of a local point, up to the translation
    above_lip = pts @ up - float((geometry.rim_vertices @ up).min())
    voxel_volume = geometry.cavity.voxel**3
    if np.ndim(sill) == 0:
        return float(np.count_nonzero(above_lip < sill)) * voxel_volume
    return np.searchsorted(np.sort(above_lip), np.asarray(sill), side="left") * voxel_volume
