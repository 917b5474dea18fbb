"""Pictures of meshes and point clouds for reports (PNG, matplotlib, no display needed)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import trimesh
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from pour_gym.parts import PART_COLORS, Part

_BASE_COLOR = np.array([0.62, 0.70, 0.80])
_LIGHT = np.array([0.4, -0.6, 0.7]) / np.linalg.norm([0.4, -0.6, 0.7])


def _face_colors(mesh: trimesh.Trimesh, labels: np.ndarray | None) -> np.ndarray:
    """Lambert-shaded RGB per face, coloured by the faces' majority vertex label."""
    if labels is None:
        base = np.tile(_BASE_COLOR, (len(mesh.faces), 1))
    else:
        palette = np.array([PART_COLORS[p] for p in Part])
        face_labels = np.asarray(labels)[mesh.faces]
        # A face takes the label most of its vertices carry (the first on a three-way tie).
        major = np.where(
            face_labels[:, 1] == face_labels[:, 2], face_labels[:, 1], face_labels[:, 0]
        )
        base = palette[major]
    shade = 0.35 + 0.65 * np.abs(mesh.face_normals @ _LIGHT)
    return np.clip(base * shade[:, None], 0.0, 1.0)


def _decimate(mesh: trimesh.Trimesh, faces: int) -> trimesh.Trimesh:
    """Quadric decimation to about ``faces`` triangles (matplotlib draws every polygon)."""
    from pour_gym.io.open3d_loader import open3d

    o3d = open3d()
    m = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(mesh.vertices)),
        o3d.utility.Vector3iVector(np.asarray(mesh.faces)),
    )
    m = m.simplify_quadric_decimation(target_number_of_triangles=faces)
    return trimesh.Trimesh(np.asarray(m.vertices), np.asarray(m.triangles), process=False)


def _part_legend(fig, parts: list[Part]) -> None:
    """A legend of part colours along the bottom of the figure."""
    handles = [
        plt.Line2D([], [], marker="s", ls="", color=PART_COLORS[p], label=p.name.lower())
        for p in parts
    ]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), frameon=False)


def save_figure(fig, path: str | Path, dpi: int = 110, tight: bool = True) -> Path:
    """Lay out, write (its folder made) and close a figure; the path written.

    ``tight=False`` keeps a layout the caller made (a legend placed outside the panels).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def _set_equal_axes(ax, points: np.ndarray) -> None:
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = (lo + hi) / 2.0, (hi - lo).max() / 2.0
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        set_lim(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))


def render_mesh(
    mesh: trimesh.Trimesh,
    path: str | Path,
    labels: np.ndarray | None = None,
    title: str | None = None,
    views: Sequence[tuple[float, float]] = ((25.0, -60.0), (70.0, -60.0)),
    max_faces: int = 40000,
) -> Path:
    """Write a PNG of a mesh from one or more viewpoints.

    Args:
        mesh: the mesh, in m.
        path: output PNG file.
        labels: optional per-vertex part labels; faces are coloured by part.
        title: figure title.
        views: (elevation, azimuth) pairs in degrees, one panel each.
        max_faces: meshes with more faces are drawn with a random subset of them.

    Returns:
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if len(mesh.faces) > max_faces and labels is None:
        mesh = _decimate(mesh, max_faces)
    colors = _face_colors(mesh, labels)
    faces = np.asarray(mesh.faces)
    if len(faces) > max_faces:
        keep = np.random.default_rng(0).choice(len(faces), max_faces, replace=False)
        faces, colors = faces[keep], colors[keep]
    tris = np.asarray(mesh.vertices)[faces]
    fig = plt.figure(figsize=(4.5 * len(views), 4.8))
    for i, (elev, azim) in enumerate(views):
        ax = fig.add_subplot(1, len(views), i + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(tris, facecolors=colors, edgecolors="none"))
        _set_equal_axes(ax, np.asarray(mesh.vertices))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
    if labels is not None:
        _part_legend(fig, [p for p in Part if np.any(np.asarray(labels) == p)])
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def render_gallery(
    meshes: Sequence[tuple[str, trimesh.Trimesh, np.ndarray | None]],
    path: str | Path,
    columns: int = 3,
    view: tuple[float, float] = (30.0, -60.0),
    dpi: int = 90,
) -> Path:
    """Write a PNG grid of labelled meshes drawn at one common scale.

    Args:
        meshes: (title, mesh, per-vertex labels or None) per panel.
        path: output PNG file.
        columns: panels per row.
        view: (elevation, azimuth) in degrees.
        dpi: pixels per inch of the 3.6-inch panels.

    Returns:
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = int(np.ceil(len(meshes) / columns))
    fig = plt.figure(figsize=(3.6 * columns, 3.6 * rows))
    half = max(float(np.ptp(m.vertices, axis=0).max()) for _, m, _ in meshes) / 2.0
    for i, (title, mesh, labels) in enumerate(meshes):
        ax = fig.add_subplot(rows, columns, i + 1, projection="3d")
        tris = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]
        ax.add_collection3d(
            Poly3DCollection(tris, facecolors=_face_colors(mesh, labels), edgecolors="none")
        )
        lo, hi = mesh.bounds
        centre = (lo + hi) / 2.0
        for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
            set_lim(c - half, c + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=view[0], azim=view[1])
        ax.set_axis_off()
        ax.set_title(title, fontsize=10)
    _part_legend(fig, list(Part))
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def render_points(
    points: np.ndarray,
    path: str | Path,
    title: str | None = None,
    view: tuple[float, float] = (25.0, -60.0),
    max_points: int = 30000,
) -> Path:
    """Write a PNG of a point cloud, coloured by height.

    Args:
        points: (N, 3) positions in m.
        path: output PNG file.
        title: figure title.
        view: (elevation, azimuth) in degrees.
        max_points: larger clouds are drawn with a random subset.

    Returns:
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pts = np.asarray(points)
    if len(pts) > max_points:
        pts = pts[np.random.default_rng(0).choice(len(pts), max_points, replace=False)]
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], c=pts[:, 2], s=0.5, cmap="viridis")
    _set_equal_axes(ax, pts)
    ax.view_init(elev=view[0], azim=view[1])
    ax.set_axis_off()
    if title:
        ax.set_title(title)
    return save_figure(fig, path)
