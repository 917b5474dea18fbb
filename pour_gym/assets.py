"""Labelled assets: the asset format, labelling a container into one, and the catalogue.

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

The repository's top-level ``assets/`` folder is installed as the package
``pour_gym.asset_files``; :func:`asset_root` finds it in a checkout and after
``pip install``. ``pour-gym build-assets`` rebuilds every catalogue asset there.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import time
import zipfile
from collections.abc import Callable
from importlib.resources import files
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.errors import ClosedContainerError, InputError, NoWaterError
from pour_gym.features import (
    CAVITY_VERSION,
    CAVITY_VOXEL,
    ContainerGeometry,
    cavity_arrays,
    cavity_from_arrays,
    container_cavity,
    container_geometry,
)
from pour_gym.io.cache import cache_dir as user_cache
from pour_gym.mesh.fileio import (
    CLOUD_SUFFIXES,
    MESH_SUFFIXES,
    load_mesh,
    load_point_cloud,
    validate_mesh,
)
from pour_gym.mesh.measure import opening_problem
from pour_gym.mesh.surface import Surface
from pour_gym.objects import procedural
from pour_gym.objects.catalogue import OBJECT_NAMES, ObjectSpec
from pour_gym.parts import PART_NAMES, Part
from pour_gym.report.tables import markdown_table

if TYPE_CHECKING:
    import trimesh

    from pour_gym.objects.build import ContainerModel

# Labelling (the warp, the builders, trimesh) is imported by the functions that label: an
# environment only loads assets, and a process that never labels stays some 60 MB lighter.

REAL_MESHES: dict[str, str] = {
    "ycb_mug": "ycb/025_mug.obj",
    "ycb_bowl": "ycb/024_bowl.obj",
}
PYBULLET_MUG = "pybullet_mug"
CATALOGUE: tuple[str, ...] = (*OBJECT_NAMES, PYBULLET_MUG, *REAL_MESHES)


def asset_root() -> Path:
    """The folder of the packaged asset files."""
    return Path(str(files("pour_gym.asset_files")))


def real_mesh_path(name: str) -> Path:
    """Path of a packaged real scanned mesh or of the mug that ships with pybullet_data.

    Args:
        name: ``ycb_mug``, ``ycb_bowl`` or ``pybullet_mug``.

    Returns:
        The mesh file (metres, z up, not watertight).

    Raises:
        InputError: unknown name.
    """
    if name == PYBULLET_MUG:
        import pybullet_data

        return Path(pybullet_data.getDataPath()) / "objects" / "mug.obj"
    try:
        return asset_root() / REAL_MESHES[name]
    except KeyError:
        raise InputError(
            f"unknown real mesh {name!r}; known: {', '.join([PYBULLET_MUG, *REAL_MESHES])}"
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
    if name in OBJECT_NAMES or procedural.is_member(name):
        model = build_object(name) if name in OBJECT_NAMES else procedural.build_member(name)
        return name, model.mesh, model
    if name in (PYBULLET_MUG, *REAL_MESHES):
        return name, load_mesh(real_mesh_path(name)), None
    path = Path(name)
    if path.exists() or path.suffix:
        return path.stem, load_mesh(path, scale), None
    raise InputError(
        f"{name!r} is neither a catalogue container ({', '.join(CATALOGUE)}) nor a mesh file"
    )


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
    part = entry.with_suffix(f".{os.getpid()}.{id(asset)}.npz")
    np.savez(
        part,
        vertices=surface.vertices, faces=surface.faces, bounds=surface.bounds,
        is_watertight=surface.is_watertight, body_count=surface.body_count,
        hull_volume=asset.hull_volume,
        rim_center=g.rim_center, rim_radius=g.rim_radius, height=g.height,
        lip_point=g.lip_point, container_volume=g.container_volume,
        cavity_volume=g.cavity_volume, rim_vertices=g.rim_vertices,
        **cavity_arrays(g.cavity, "cavity_"),
    )  # fmt: skip
    os.replace(part, entry)  # whole or not at all: a reader never sees half a file


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


# Bumped when labelling a file gives another result for the same bytes (the cache of
# labelled user meshes is keyed by both). 2: STL corners joined into shared vertices. 3: the
# warped rim fitted to the lip (pour_gym.warp.lip).
LABELLING_VERSION = 3

# Containers by split, for environments: the thesis trained on the red cup alone and
# tested on its other eight objects.
SPLITS: dict[str, tuple[str, ...]] = {
    "train": ("red_cup",),
    "test": tuple(n for n in OBJECT_NAMES if n != "red_cup"),
    "all": tuple(OBJECT_NAMES),
    "real": (PYBULLET_MUG, *REAL_MESHES),
}


def expand_containers(spec: str | Path | list | tuple) -> tuple[str, ...]:
    """Container names or paths from a split name, a name, a path, or a list of them.

    Args:
        spec: ``"train"``, ``"test"``, ``"all"``, ``"real"``, a procedural family
            (``"procedural:test"``, see :mod:`pour_gym.objects.procedural`), a catalogue
            name, a procedural member, an asset directory, a mesh or point cloud file, a
            comma-separated string or a list of them.

    Returns:
        The containers, in order, as strings.

    Raises:
        InputError: an empty list, or an entry that is neither a known name nor a path.
    """
    if isinstance(spec, str | Path):
        s = str(spec)
        if s in SPLITS:
            return SPLITS[s]
        # "a,b,c" lists containers (unless it is the name of an existing file).
        spec = s.split(",") if "," in s and not Path(s).exists() else [s]
    items: tuple[str, ...] = ()
    for x in spec:  # a split or a family inside a list stands for its containers
        x = str(x)
        items += procedural.family_members(x) if procedural.is_family(x) else SPLITS.get(x, (x,))
    items = tuple(dict.fromkeys(items))
    if not items:
        raise InputError("no containers given; use a split (train, test, all, real) or names")
    for item in items:
        p = Path(item)
        readable = (*MESH_SUFFIXES, *CLOUD_SUFFIXES)
        if item in CATALOGUE or p.is_dir() or (p.is_file() and p.suffix.lower() in readable):
            continue
        if item.startswith(procedural.PREFIX):
            procedural.member_spec(item)  # an InputError naming what is wrong with it
            continue
        raise InputError(
            f"{item!r} is not a container: use a split ({', '.join(SPLITS)}), a procedural "
            f"family (procedural:train, procedural:test, procedural:N@SEED), a catalogue "
            f"name ({', '.join(CATALOGUE)}), an asset directory, a mesh file "
            f"({', '.join(MESH_SUFFIXES)}) or a point cloud file ({', '.join(CLOUD_SUFFIXES)})"
        )
    return items


def cache_entry(key: bytes, stem: str, cache_dir: str | Path | None = None) -> Path:
    """The folder of the cached asset with this key (it may not exist yet).

    Args:
        key: what the asset is a function of (file bytes, names, versions, settings).
        stem: the start of its folder's name, for people reading the cache.
        cache_dir: where assets are kept (default: the user cache's ``assets``).
    """
    root = Path(cache_dir) if cache_dir is not None else user_cache("assets")
    stem = re.sub(r"[^A-Za-z0-9]+", "_", stem)
    return root / f"{stem}_{hashlib.sha256(key).hexdigest()[:16]}"


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

    target = cache_entry(key, stem, cache_dir)
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


def resolve_asset(spec: str | Path, cache_dir: str | Path | None = None) -> LabelledAsset:
    """A labelled asset from a name, an asset directory, a mesh file or a point cloud file.

    A catalogue name or an asset directory is loaded as it is. A mesh file or a procedural
    member (``procedural:test#7``) is labelled by warping the red cup onto it (about a
    second for 20k vertices); a point cloud file is reconstructed first (chapter 3: 5-15
    s). The result is cached under ``cache_dir`` by the file's content (a member: by its
    name and the generator's version), so the next call loads it.

    Args:
        spec: catalogue name, asset directory, procedural member, mesh file (in m, any
            pose) or point cloud file (in m, upright).
        cache_dir: where labelled user meshes are kept (default: the user cache).

    Raises:
        InputError: not a container, or a mesh or cloud that cannot be labelled.
    """
    s = str(spec)
    p = Path(s)
    if s in CATALOGUE or p.is_dir():
        return load_asset(s)
    if procedural.is_member(s):
        key = f"{s} g{procedural.GENERATOR_VERSION} v{LABELLING_VERSION}".encode()
        return cached_asset(key, s, lambda: label_container(s), cache_dir)
    if p.is_file() and is_point_cloud_file(p):
        from pour_gym.mesh.reconstruct import RECONSTRUCTION_VERSION

        key = p.read_bytes() + f"cloud r{RECONSTRUCTION_VERSION} v{LABELLING_VERSION}".encode()
        return cached_asset(key, p.stem, lambda: label_point_cloud(p), cache_dir)
    if p.is_file():
        key = p.read_bytes() + f"v{LABELLING_VERSION}".encode()
        return cached_asset(key, p.stem, lambda: label_container(s), cache_dir)
    raise InputError(
        f"no container {s!r}: not a catalogue name, procedural member, asset directory or file"
    )


def warping_tables(reports: dict[str, dict]) -> str:
    """Tables 4.1-4.3 and per-part IoU beside the thesis's numbers."""
    out = []
    for key, title, unit, factor in (
        ("height", "Table 4.1: height", "cm", 100.0),
        ("rim_radius", "Table 4.2: rim radius", "cm", 100.0),
        ("volume", "Table 4.3: volume (cavity below the rim)", "ml", 1e6),
        ("volume_convex_hull", "Table 4.3: volume (convex hull, thesis 5.1)", "ml", 1e6),
    ):
        out.append(f"### {title}\n")
        header = ["object", f"real {unit}", f"thesis {unit}", "thesis error",
                  f"thesis method {unit}", "error", f"best {unit}", "error"]  # fmt: skip
        rows = []
        errs = np.zeros(3)
        for name, by_method in reports.items():
            t = by_method["thesis"]["tables"][key]
            b = by_method["best"]["tables"][key]
            errs += [t["thesis_rel_error"], t["rel_error"], b["rel_error"]]
            rows.append([
                name, f"{t['real'] * factor:.2f}", f"{t['thesis_computed'] * factor:.2f}",
                f"{t['thesis_rel_error']:.1%}", f"{t['computed'] * factor:.2f}",
                f"{t['rel_error']:.1%}", f"{b['computed'] * factor:.2f}", f"{b['rel_error']:.1%}",
            ])  # fmt: skip
        m = errs / len(reports)
        rows.append(["**mean**", "", "", f"**{m[0]:.1%}**", "", f"**{m[1]:.1%}**", "",
                     f"**{m[2]:.1%}**"])  # fmt: skip
        out.append(markdown_table(header, rows) + "\n")
    out.append("### Per-part IoU against ground truth (thesis method / best)\n")
    rows = []
    for name, by_method in reports.items():
        cells = []
        for part in ("rim", "handle", "container", "outside"):
            pair = (by_method["thesis"]["iou"][part], by_method["best"]["iou"][part])
            cells.append(" / ".join("-" if v is None else f"{v:.2f}" for v in pair))
        rows.append([name, *cells])
    out.append(markdown_table(["object", "rim", "handle", "container", "outside"], rows))
    return "\n".join(out)
