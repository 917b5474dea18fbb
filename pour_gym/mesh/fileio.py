"""Reading and writing point clouds and meshes, with checks that name the problem.

Point clouds: PLY and PCD (open3d), XYZ (text, 3 or 6 columns: x y z [nx ny nz]) and NPY
((N, 3) or (N, 6) arrays). Meshes: OBJ, STL, PLY, GLB/GLTF, OFF (trimesh). Everything is
in metres; ``scale`` converts on the way in (0.001 for millimetres).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.errors import InputError
from pour_gym.io.open3d_loader import open3d

if TYPE_CHECKING:
    import trimesh

    from pour_gym.mesh.scan import PointCloud

CLOUD_SUFFIXES = (".ply", ".pcd", ".xyz", ".npy")
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf", ".off")


def _existing(path: str | Path, suffixes: tuple[str, ...], kind: str) -> Path:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{kind} file not found: {path}")
    if path.suffix.lower() not in suffixes:
        raise InputError(
            f"cannot read {kind} file {path.name!r}: the format {path.suffix or '(none)'!r} is "
            f"not supported; use one of {', '.join(suffixes)}"
        )
    return path


def load_point_cloud(path: str | Path, scale: float = 1.0) -> PointCloud:
    """Read a point cloud (and its normals, when the file has them).

    Args:
        path: a .ply, .pcd, .xyz or .npy file.
        scale: factor applied to the coordinates (0.001 turns millimetres into metres).

    Returns:
        The cloud in m.

    Raises:
        InputError: missing file, unsupported format, unreadable or empty content.
    """
    path = _existing(path, CLOUD_SUFFIXES, "point cloud")
    suffix = path.suffix.lower()
    normals = None
    if suffix in (".ply", ".pcd"):
        o3d = open3d()
        pcd = o3d.io.read_point_cloud(str(path))
        points = np.asarray(pcd.points, dtype=np.float64)
        if pcd.has_normals():
            normals = np.asarray(pcd.normals, dtype=np.float64)
    else:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # an empty file is reported below, once
                raw = np.load(path) if suffix == ".npy" else np.loadtxt(path, ndmin=2)
        except Exception as exc:
            raise InputError(f"cannot parse {path.name}: {exc}") from None
        raw = np.asarray(raw, dtype=np.float64)
        if raw.ndim != 2 or raw.shape[1] not in (3, 6):
            raise InputError(
                f"{path.name} holds an array of shape {raw.shape}; expected (N, 3) points or "
                "(N, 6) points with normals"
            )
        points = raw[:, :3]
        normals = raw[:, 3:] if raw.shape[1] == 6 else None
    if len(points) == 0:
        raise InputError(f"{path.name} contains no points")
    from pour_gym.mesh.scan import PointCloud

    return PointCloud(
        points=points * scale,
        normals=normals,
        meta={"source": str(path), "scale": scale, "n_points": len(points)},
    )


def save_point_cloud(cloud: PointCloud, path: str | Path) -> Path:
    """Write a point cloud as .ply, .pcd, .xyz or .npy (with normals when it has them).

    Args:
        cloud: the cloud, in m.
        path: output file; the suffix selects the format.

    Returns:
        The path written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in CLOUD_SUFFIXES:
        raise InputError(f"cannot write {path.name}: use one of {', '.join(CLOUD_SUFFIXES)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    data = cloud.points if cloud.normals is None else np.hstack([cloud.points, cloud.normals])
    if suffix == ".npy":
        np.save(path, data)
    elif suffix == ".xyz":
        np.savetxt(path, data, fmt="%.7f")
    else:
        o3d = open3d()
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(cloud.points))
        if cloud.normals is not None:
            pcd.normals = o3d.utility.Vector3dVector(cloud.normals)
        o3d.io.write_point_cloud(str(path), pcd)
    return path


def load_mesh(path: str | Path, scale: float = 1.0) -> trimesh.Trimesh:
    """Read a triangle mesh, keeping its vertices in the file's order.

    Scenes (GLB, multi-object OBJ) are merged into one mesh.

    Args:
        path: a mesh file.
        scale: factor applied to the coordinates (0.001 turns millimetres into metres).

    Returns:
        The mesh in m, unprocessed (no merging or reordering of vertices), except that an
        STL's equal triangle corners become shared vertices (the format repeats them).

    Raises:
        InputError: missing file, unsupported format, no triangles.
    """
    path = _existing(path, MESH_SUFFIXES, "mesh")
    try:
        import trimesh

        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:
        raise InputError(f"cannot read mesh {path.name}: {exc}") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise InputError(f"{path.name} contains no triangles")
    if path.suffix.lower() == ".stl":
        loaded = _shared_corners(loaded)
    if scale != 1.0:
        loaded.apply_scale(scale)
    return loaded


def _shared_corners(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """An STL's triangles with equal corners joined into shared vertices.

    STL stores every triangle's three corners apart, so read as it stands no mesh is
    watertight; the vertices keep the order of their first appearance.
    """
    v = np.asarray(mesh.vertices)
    _, first, inverse = np.unique(v, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    faces = rank[inverse.ravel()][np.asarray(mesh.faces)]
    import trimesh

    return trimesh.Trimesh(v[first[order]], faces, process=False)


def validate_mesh(mesh: trimesh.Trimesh, name: str = "mesh", watertight: bool = False) -> None:
    """Check that a mesh can be a container in metres.

    Args:
        mesh: the mesh.
        name: how to call it in messages.
        watertight: also require a closed surface.

    Raises:
        InputError: no faces, NaN coordinates, zero area, a size that is not metres, or
            (with ``watertight``) holes.
    """
    v = np.asarray(mesh.vertices)
    if len(mesh.faces) == 0 or len(v) < 4:
        raise InputError(f"{name} has no triangles")
    if not np.isfinite(v).all():
        raise InputError(f"{name} has NaN or infinite vertex coordinates")
    extent = float(np.ptp(v, axis=0).max())
    if mesh.area <= 0.0 or extent <= 0.0:
        raise InputError(f"{name} is degenerate: its triangles have no area")
    if extent > 2.0:
        raise InputError(
            f"{name} is {extent:g} units across, too large for a container in metres; if it "
            "is in millimetres pass --scale 0.001"
        )
    if extent < 0.01:
        raise InputError(f"{name} is only {extent:g} m across; check its units (--scale)")
    if watertight and not mesh.is_watertight:
        raise InputError(
            f"{name} is not watertight (it has holes or open edges); this step needs a closed "
            "surface: repair it first (e.g. trimesh.repair.fill_holes) or reconstruct it from "
            "a scan (pour-gym reconstruct)"
        )


def save_mesh(mesh: trimesh.Trimesh, path: str | Path) -> Path:
    """Write a mesh; the suffix selects the format (.obj, .stl, .ply, .glb, .off).

    Args:
        mesh: the mesh, in m.
        path: output file.

    Returns:
        The path written.
    """
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise InputError(f"cannot write {path.name}: use one of {', '.join(MESH_SUFFIXES)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(path)
    return path


def is_point_cloud_file(path: str | Path) -> bool:
    """Whether a file holds a point cloud rather than a mesh (a PLY with no faces is one)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in CLOUD_SUFFIXES:
        return False
    if suffix not in MESH_SUFFIXES:
        return True
    with open(path, "rb") as fh:  # a PLY: its header says whether it has faces
        header = fh.read(4096).split(b"end_header")[0].decode("ascii", "replace")
    faces = re.search(r"element\s+face\s+(\d+)", header)
    return faces is None or int(faces.group(1)) == 0
