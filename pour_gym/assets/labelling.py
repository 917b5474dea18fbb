"""Labelling a container: the red cup's labels warped onto its mesh (chapter 4), and cached.

:func:`label_container` makes a :class:`~pour_gym.assets.format.LabelledAsset` of any mesh
(a catalogue object's also scored against its ground truth, with the thesis's table
rows); :func:`label_point_cloud` reconstructs a cloud first (chapter 3);
:func:`cached_asset` keeps what was labelled in the user cache, keyed by what it is a
function of.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.assets.catalogue import parse_container, real_mesh_path
from pour_gym.assets.format import (
    LabelledAsset,
    canonical_coordinates,
    canonical_transform,
    load_asset,
    write_asset,
)
from pour_gym.errors import ClosedContainerError, InputError, NoWaterError
from pour_gym.features import ContainerGeometry, container_cavity, container_geometry
from pour_gym.io.cache import keyed_entry
from pour_gym.mesh.fileio import load_mesh, load_point_cloud, validate_mesh
from pour_gym.mesh.measure import opening_problem
from pour_gym.objects import procedural
from pour_gym.objects.catalogue import OBJECT_NAMES, ObjectSpec
from pour_gym.parts import PART_NAMES, Part

if TYPE_CHECKING:
    import trimesh

    from pour_gym.objects.build import ContainerModel

# Labelling (the warp, the builders, trimesh) is imported by the functions that label: an
# environment only loads assets, and a process that never labels stays some 60 MB lighter.


def part_iou(predicted: np.ndarray, truth: np.ndarray) -> dict[str, float | None]:
    """Intersection over union of each part's vertex set (None where neither has the part)."""
    out: dict[str, float | None] = {}
    for part in Part:
        a, b = predicted == part, truth == part
        union = int(np.count_nonzero(a | b))
        out[part.name.lower()] = None if union == 0 else float(np.count_nonzero(a & b) / union)
    return out


def _table_rows(model: ContainerModel, geometry: ContainerGeometry) -> dict:
    """The thesis's Tables 4.1-4.3 rows for one object: real, computed here, paper."""
    spec = model.spec
    rows = {}
    for key, real, computed, paper in (
        ("height", spec.height, geometry.height, spec.thesis_height),
        ("rim_radius", spec.rim_radius, geometry.rim_radius, spec.thesis_rim_radius),
        ("volume", spec.volume, geometry.cavity_volume, spec.thesis_volume),
        ("volume_convex_hull", spec.volume, geometry.container_volume, spec.thesis_volume),
    ):
        rows[key] = {
            "real": real,
            "computed": computed,
            "abs_error": abs(computed - real),
            "rel_error": abs(computed - real) / real,
            "thesis_computed": paper,
            "thesis_rel_error": abs(paper - real) / real,
        }
    return rows


def _source_model(source: str) -> ContainerModel:
    if source not in OBJECT_NAMES:
        raise InputError(
            f"the source must be a labelled thesis object ({', '.join(OBJECT_NAMES)}); "
            f"got {source!r}"
        )
    from pour_gym.objects import build_object

    return build_object(source)


def _transfer(src: ContainerModel, mesh: trimesh.Trimesh, method: str, upright: bool):
    """Labels of ``mesh`` warped from ``src`` by ``method``, and the mesh's canonical frame."""
    from pour_gym.warp.frame import canonical_frame
    from pour_gym.warp.transfer import transfer_best, transfer_thesis

    if method == "best":
        result = transfer_best(src.mesh, src.labels, mesh, target_upright=upright)
        return result, result.frame
    return transfer_thesis(src.mesh, src.labels, mesh), canonical_frame(mesh, upright=upright)


def label_container(
    target: str | Path | trimesh.Trimesh,
    source: str = "red_cup",
    method: str = "best",
    scale: float = 1.0,
    allow_closed: bool = False,
    name: str | None = None,
) -> LabelledAsset:
    """Label a container's parts by warping a labelled source onto it.

    Args:
        target: a catalogue name, a mesh file (any pose and size, in m after ``scale``),
            or a mesh.
        source: the labelled thesis object to warp from.
        method: ``"best"`` or ``"thesis"`` (see :mod:`pour_gym.warp.transfer`).
        scale: factor to metres for mesh files.
        allow_closed: label a container whose opening is closed (a capped scan) anyway;
            its asset records why it looks closed, and environments refuse it.
        name: the asset's name (default: the catalogue name or the file's stem; "mesh"
            for a mesh given as such).

    Returns:
        The labelled asset, in its canonical frame.

    Raises:
        InputError: unknown names, a method other than the two, a degenerate or tiny mesh,
            a mesh that holds no water.
        ClosedContainerError: the container has no opening (unless ``allow_closed``).
    """
    import trimesh

    if method not in ("best", "thesis"):
        raise InputError(f"unknown method {method!r}; use 'best' or 'thesis'")
    t0 = time.perf_counter()
    found, mesh, truth = resolve_target(target, scale)
    name = name or found
    validate_mesh(mesh, name=name)
    src = _source_model(source)
    # A mesh that holds no water however it is turned has no opening to find "up" by: with
    # allow_closed it is taken as it stands (its +z up), and labelled anyway.
    try:
        result, frame = _transfer(src, mesh, method, upright=False)
    except NoWaterError:
        if not allow_closed:
            raise ClosedContainerError(name, "it holds no water however it is turned") from None
        result, frame = _transfer(src, mesh, method, upright=True)
    assert frame is not None
    transform = canonical_transform(frame.transform)
    moved = np.asarray(mesh.vertices) @ transform[:3, :3].T + transform[:3, 3]
    placed = trimesh.Trimesh(canonical_coordinates(moved), mesh.faces, process=False)
    water = container_cavity(placed)
    closed = opening_problem(water, float(placed.convex_hull.volume))
    if closed is not None and not allow_closed:
        raise ClosedContainerError(name, closed)
    labels = result.labels.astype(np.int8)
    try:
        geometry = container_geometry(placed, labels, water=water)
    except InputError as exc:  # what the warp found on a mesh with no cavity to map onto
        raise InputError(f"{name} could not be labelled: {exc}") from None
    meta: dict = {
        "name": name,
        "labels": PART_NAMES,
        **geometry.to_dict(),
        "transform": transform.tolist(),
        "watertight": bool(mesh.is_watertight),
        "vertices": len(mesh.vertices),
        "source": {"object": source, "method": method, "transfer": result.info},
        "closed": closed,
        "seconds": time.perf_counter() - t0,
    }
    if truth is not None:
        # The built meshes are upright with the handle along +x and the canonical frame
        # keeps the vertices' order: labels compare vertex by vertex.
        meta["iou"] = part_iou(labels, truth.labels)
        if isinstance(truth.spec, ObjectSpec):
            meta["tables"] = _table_rows(truth, geometry)
        else:
            meta["procedural"] = truth.spec.to_dict()
    return LabelledAsset(name=name, mesh=placed, labels=labels, geometry=geometry, meta=meta)


# Bumped when labelling a file gives another result for the same bytes (the cache of
# labelled user meshes is keyed by both). 2: STL corners joined into shared vertices. 3: the
# warped rim fitted to the lip (pour_gym.warp.lip).
LABELLING_VERSION = 3


def cached_asset(
    key: bytes, stem: str, make: Callable[[], LabelledAsset], cache_dir: str | Path | None = None
) -> LabelledAsset:
    """A labelled asset from the cache, made (and kept there) on the first call.

    Args:
        key: what the asset is a function of (file bytes, names, versions, settings).
        stem: the start of its folder's name, for people reading the cache.
        make: makes the asset when it is not cached.
        cache_dir: where assets are kept (default: the user cache's ``assets``).

    Returns:
        The asset as loaded from its folder (so a made asset and a cached one are the
        same numbers).
    """
    import shutil

    target = keyed_entry(key, stem, cache_dir)
    if not (target / "meta.json").is_file():
        # Written aside and renamed, so that environments in parallel processes never
        # read a half-written asset.
        tmp = target.parent / f".{target.name}.{os.getpid()}"
        write_asset(make(), tmp, picture=False)
        try:
            tmp.rename(target)
        except OSError:  # another process got there first
            shutil.rmtree(tmp, ignore_errors=True)
    return load_asset(target)


def label_point_cloud(path: str | Path) -> LabelledAsset:
    """A container from a point cloud file: reconstructed (chapter 3), then labelled.

    Args:
        path: a .ply (without faces), .pcd, .xyz or .npy file in m, the container upright.

    Raises:
        InputError: a cloud that cannot be reconstructed (its units, say) or labelled.
    """
    from pour_gym.mesh.reconstruct import reconstruct

    cloud = load_point_cloud(path)
    name = Path(path).stem
    try:
        return label_container(reconstruct(cloud).mesh, name=name)
    except ClosedContainerError as exc:
        raise InputError(
            f"the point cloud {path} gave a closed surface ({exc.problem}); a cloud whose "
            "points do not show the opening cannot be made a container"
        ) from None


def resolve_target(target: str | Path | trimesh.Trimesh, scale: float = 1.0):
    """A labelling target as (name, mesh, ground-truth model or None).

    Args:
        target: a catalogue name, a procedural member (``procedural:test#7``), a mesh
            file, or a mesh.
        scale: factor to metres for mesh files.

    Raises:
        InputError: neither a catalogue name, a procedural member nor a readable mesh.
    """
    import trimesh

    from pour_gym.objects import build_object

    if isinstance(target, trimesh.Trimesh):
        return "mesh", target, None
    name = str(target)
    if not Path(name).exists() and Path(name).suffix and not name.startswith(procedural.PREFIX):
        load_mesh(name, scale)  # a missing file: the reader's error names it
    c = parse_container(name)
    if c.kind == "member" or name in OBJECT_NAMES:
        model = build_object(name) if name in OBJECT_NAMES else procedural.build_member(name)
        return name, model.mesh, model
    if c.kind == "catalogue":  # a real mesh
        return name, load_mesh(real_mesh_path(name)), None
    if c.kind == "mesh_file":
        return c.path.stem, load_mesh(c.path, scale), None
    raise InputError(
        f"{name!r} is a {c.kind.replace('_', ' ')}: labelling takes a catalogue container, "
        "a procedural member or a mesh file"
    )
