"""The labelled asset format: a container's mesh in its canonical frame with a part per vertex.

An asset directory holds (the contract other tools read):

- ``mesh.obj``: the target's own vertices, in the input's order (no merging or
  reordering), moved into the canonical frame: upright, base on z = 0, rim axis on the z
  axis, handle along +x;
- ``labels.npy``: one int8 part per vertex (see :class:`pour_gym.parts.Part`);
- ``meta.json``: ``labels`` (the part names' values), ``rim_center``, ``rim_radius``,
  ``height``, ``lip_point``, ``container_volume`` (convex hull, thesis 5.1) and
  ``cavity_volume`` in m and m^3, ``transform`` (input -> asset frame, 4 x 4), ``source``
  (what it was warped from and how) and, for catalogue targets, ``iou`` per part and the
  thesis's table rows;
- ``labels.png``: a picture of the labelled mesh.

:func:`load_asset` keeps each folder's loaded form (arrays, topology, hull, geometry) in
the user cache (``loaded``), so a process that pours neither imports trimesh nor
recomputes them.
"""

from __future__ import annotations

import hashlib
import json
import re
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.assets.catalogue import CATALOGUE, asset_root
from pour_gym.errors import ClosedContainerError, InputError
from pour_gym.features import (
    CAVITY_VERSION,
    CAVITY_VOXEL,
    ContainerGeometry,
    cavity_arrays,
    cavity_from_arrays,
    container_geometry,
)
from pour_gym.io.cache import cache_dir as user_cache
from pour_gym.io.cache import write_npz
from pour_gym.mesh.fileio import load_mesh
from pour_gym.mesh.measure import opening_problem
from pour_gym.mesh.surface import Surface

if TYPE_CHECKING:
    import trimesh


class LabelledAsset:
    """A labelled container in its canonical frame.

    Attributes:
        name: the asset's name.
        labels: (V,) int8 part per vertex.
        geometry: container geometry from the labels.
        meta: everything ``meta.json`` holds.
        surface: the mesh's arrays and topology (:class:`~pour_gym.mesh.surface.Surface`).
        mesh: the mesh in the canonical frame, vertices in the input's order, as a trimesh
            (an asset loaded from the cache makes it from :attr:`surface` when first read).
        hull_volume: the volume of the mesh's convex hull, in m^3.
    """

    def __init__(
        self,
        name: str,
        mesh: trimesh.Trimesh | Surface,
        labels: np.ndarray,
        geometry: ContainerGeometry,
        meta: dict,
        hull_volume: float | None = None,
    ):
        self.name = name
        self.labels = labels
        self.geometry = geometry
        self.meta = meta
        self._mesh = None if isinstance(mesh, Surface) else mesh
        self._surface = mesh if isinstance(mesh, Surface) else None
        self._hull_volume = hull_volume

    @property
    def mesh(self) -> trimesh.Trimesh:
        """The mesh as a trimesh (made from :attr:`surface` on first use)."""
        if self._mesh is None:
            self._mesh = self.surface.to_trimesh()
        return self._mesh

    @property
    def surface(self) -> Surface:
        """The mesh's arrays and topology, without trimesh."""
        if self._surface is None:
            self._surface = Surface.of(self.mesh)
        return self._surface

    @property
    def hull_volume(self) -> float:
        """The volume of the mesh's convex hull, in m^3 (kept once computed)."""
        if self._hull_volume is None:
            self._hull_volume = float(self.mesh.convex_hull.volume)
        return self._hull_volume

    def __repr__(self) -> str:
        return f"LabelledAsset({self.name!r}, {len(self.labels)} vertices)"


# What an asset's numbers mean: coordinates to 0.1 micrometre (the OBJ's 7 decimals in m);
# transform entries within this of 0 or +-1 are those values (floating-point dust otherwise,
# which differs between CPUs and BLAS builds).
COORDINATE_DECIMALS = 7
SNAP = 1e-12


def canonical_coordinates(values: np.ndarray) -> np.ndarray:
    """Values rounded to 0.1 micrometre, with no negative zero.

    The same asset rebuilt on another machine then writes the same text wherever the
    machines agree to 0.1 micrometre (a ``-0.0000000`` would otherwise differ from
    ``0.0000000`` by a sign of floating-point dust).
    """
    # Adding +0.0 turns -0.0 into +0.0 (IEEE 754), after rounding made it.
    return np.round(np.asarray(values, dtype=np.float64), COORDINATE_DECIMALS) + 0.0


def canonical_transform(transform: np.ndarray) -> np.ndarray:
    """A rigid transform with entries within 1e-12 of 0, 1 or -1 snapped to them."""
    t = np.array(transform, dtype=np.float64)
    for value in (0.0, 1.0, -1.0):
        t[np.abs(t - value) < SNAP] = value
    return t + 0.0


def write_asset(asset: LabelledAsset, out: str | Path, picture: bool = True) -> Path:
    """Write an asset directory (``mesh.obj``, ``labels.npy``, ``meta.json``, ``labels.png``).

    Args:
        asset: the labelled asset.
        out: the directory (created).
        picture: also draw ``labels.png``.

    Returns:
        The directory.
    """
    import trimesh

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    # Canonical coordinates at fixed precision and no normals: small files, and a rebuild
    # on the same machine writes the same bytes.
    mesh = trimesh.Trimesh(
        canonical_coordinates(asset.mesh.vertices), asset.mesh.faces, process=False
    )
    obj = trimesh.exchange.obj.export_obj(
        mesh, include_normals=False, include_texture=False, digits=COORDINATE_DECIMALS
    )
    (out / "mesh.obj").write_text(obj)
    np.save(out / "labels.npy", asset.labels)
    meta = {k: v for k, v in asset.meta.items() if k != "seconds"}
    (out / "meta.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    if picture:
        from pour_gym.report.pictures import render_mesh

        render_mesh(asset.mesh, out / "labels.png", labels=asset.labels, title=asset.name)
    return out


def load_asset(name_or_dir: str | Path) -> LabelledAsset:
    """Load a labelled asset by catalogue name (packaged) or from a directory.

    Args:
        name_or_dir: a name under :func:`asset_root` or a path to an asset directory.

    Returns:
        The asset; its geometry is recomputed from mesh and labels.

    Raises:
        InputError: no such asset, or files missing.
    """
    path = Path(name_or_dir)
    if not path.is_dir():
        path = asset_root() / str(name_or_dir)
    files_needed = [path / f for f in ("mesh.obj", "labels.npy", "meta.json")]
    missing = [f.name for f in files_needed if not f.is_file()]
    if missing:
        raise InputError(
            f"no labelled asset at {path} (missing {', '.join(missing)}); known assets: "
            f"{', '.join(CATALOGUE)}; build them with pour-gym build-assets"
        )
    labels = np.load(path / "labels.npy")
    meta = json.loads((path / "meta.json").read_text())
    name = meta.get("name", path.name)
    entry = _loaded_entry(path, labels, name)
    if entry.is_file():
        try:
            return _read_loaded(entry, name, labels, meta)
        except (OSError, KeyError, ValueError, zipfile.BadZipFile):
            pass  # a damaged entry (a full disk, say) is made again below
    mesh = load_mesh(path / "mesh.obj")
    asset = LabelledAsset(name, mesh, labels, container_geometry(mesh, labels), meta)
    _write_loaded(entry, asset)
    return asset


# Bumped when what a loaded asset holds, or how it is computed from the folder, changes.
LOADED_VERSION = 1


def _loaded_entry(path: Path, labels: np.ndarray, name: str) -> Path:
    """Where an asset folder's loaded form is kept: keyed by its mesh and labels' bytes."""
    h = hashlib.sha256((path / "mesh.obj").read_bytes())
    h.update(np.ascontiguousarray(labels).tobytes())
    h.update(f"{labels.dtype} {labels.shape} l{LOADED_VERSION}".encode())
    h.update(f" c{CAVITY_VERSION} {CAVITY_VOXEL!r}".encode())
    stem = re.sub(r"[^A-Za-z0-9]+", "_", name)[:60]
    return user_cache("loaded") / f"{stem}_{h.hexdigest()[:16]}.npz"


def _write_loaded(entry: Path, asset: LabelledAsset) -> None:
    """Keep an asset's arrays, topology and geometry as loading computed them.

    What the next load reads instead of parsing the OBJ with trimesh and computing the
    convex hulls and the cavity again: the same float64 numbers, so an environment's
    episodes are the same bits from a fresh folder or from this entry.
    """
    surface, g = asset.surface, asset.geometry
    write_npz(
        entry,
        compressed=False,
        vertices=surface.vertices, faces=surface.faces, bounds=surface.bounds,
        is_watertight=surface.is_watertight, body_count=surface.body_count,
        hull_volume=asset.hull_volume,
        rim_center=g.rim_center, rim_radius=g.rim_radius, height=g.height,
        lip_point=g.lip_point, container_volume=g.container_volume,
        cavity_volume=g.cavity_volume, rim_vertices=g.rim_vertices,
        **cavity_arrays(g.cavity, "cavity_"),
    )  # fmt: skip


def _read_loaded(entry: Path, name: str, labels: np.ndarray, meta: dict) -> LabelledAsset:
    """An asset from its loaded form (:func:`_write_loaded`), without trimesh or SciPy."""
    with np.load(entry) as d:
        cavity = cavity_from_arrays(d, "cavity_")
        geometry = ContainerGeometry(
            rim_center=d["rim_center"],
            rim_radius=float(d["rim_radius"]),
            height=float(d["height"]),
            lip_point=d["lip_point"],
            container_volume=float(d["container_volume"]),
            cavity_volume=float(d["cavity_volume"]),
            rim_vertices=d["rim_vertices"],
            cavity=cavity,
        )
        surface = Surface(
            vertices=d["vertices"],
            faces=d["faces"],
            bounds=d["bounds"],
            is_watertight=bool(d["is_watertight"]),
            body_count=int(d["body_count"]),
        )
        hull = float(d["hull_volume"])
    return LabelledAsset(name, surface, labels, geometry, meta, hull_volume=hull)


def check_open(asset: LabelledAsset, spec: str | Path | None = None) -> LabelledAsset:
    """The asset, if its container has an opening (environments pour only into those).

    Raises:
        ClosedContainerError: the container looks closed, whatever it was labelled with.
    """
    closed = opening_problem(asset.geometry.cavity, asset.hull_volume)
    if closed is not None:
        raise ClosedContainerError(str(spec or asset.name), closed, flag=False)
    return asset
