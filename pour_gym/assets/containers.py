"""The one parser of a container as users name it, and what each kind resolves to.

Whatever ``objects=`` or a command takes (a split, a procedural family, a catalogue name, a
procedural member, an asset folder, a mesh file, a point cloud file, or a list of them)
goes through :func:`expand_containers` (splits, families and lists into single
containers) and :func:`parse_container` (one container into a tagged
:class:`ContainerSpec`, or an :class:`~pour_gym.errors.InputError` that says what it
takes); :func:`resolve_asset` (a labelled asset) and :func:`resolve_target` (a mesh to
label) dispatch on the tag.
"""

from __future__ import annotations

from pathlib import Path

from pour_gym.assets.catalogue import SPLITS, ContainerSpec, parse_container
from pour_gym.assets.format import LabelledAsset, load_asset
from pour_gym.assets.labelling import (
    LABELLING_VERSION,
    cached_asset,
    label_container,
    label_point_cloud,
)
from pour_gym.errors import InputError
from pour_gym.objects import procedural


def _existing_path(s: str) -> bool:
    """Whether ``s`` names an existing file or folder.

    A list of many names is too long to be one: the system refuses to look it up, which is
    an answer, not an error.
    """
    try:
        return Path(s).exists()
    except OSError:
        return False


def expand_containers(spec: str | Path | list | tuple) -> tuple[str, ...]:
    """Container names or paths from a split name, a name, a path, or a list of them.

    Args:
        spec: ``"train"``, ``"test"``, ``"all"``, ``"real"``, a procedural family
            (``"procedural:test"``, see :mod:`pour_gym.objects.procedural`), a catalogue
            name, a procedural member, an asset directory, a mesh or point cloud file, a
            comma-separated string or a list of them.

    Returns:
        The containers, in order, as strings, each one :func:`parse_container` takes.

    Raises:
        InputError: an empty list, or an entry that is neither a known name nor a path.
    """
    if isinstance(spec, str | Path):
        s = str(spec)
        if s in SPLITS:
            return SPLITS[s]
        # "a,b,c" lists containers (unless it is the name of an existing file).
        spec = s.split(",") if "," in s and not _existing_path(s) else [s]
    items: tuple[str, ...] = ()
    for x in spec:  # a split or a family inside a list stands for its containers
        x = str(x)
        items += procedural.family_members(x) if procedural.is_family(x) else SPLITS.get(x, (x,))
    items = tuple(dict.fromkeys(items))
    if not items:
        raise InputError("no containers given; use a split (train, test, all, real) or names")
    for item in items:
        parse_container(item)
    return items


def resolve_asset(
    spec: str | Path | ContainerSpec, cache_dir: str | Path | None = None
) -> LabelledAsset:
    """A labelled asset from a name, an asset directory, a mesh file or a point cloud file.

    A catalogue name or an asset directory is loaded as it is. A mesh file or a procedural
    member (``procedural:test#7``) is labelled by warping the red cup onto it (about a
    second for 20k vertices); a point cloud file is reconstructed first (chapter 3: 5-15
    s). The result is cached under ``cache_dir`` by the file's content (a member: by its
    name and the generator's version), so the next call loads it.

    Args:
        spec: catalogue name, asset directory, procedural member, mesh file (in m, any
            pose) or point cloud file (in m, upright), or its :class:`ContainerSpec`.
        cache_dir: where labelled user meshes are kept (default: the user cache).

    Raises:
        InputError: not a container, or a mesh or cloud that cannot be labelled.
    """
    c = parse_container(spec)
    s, p = c.text, c.path
    if c.kind in ("catalogue", "asset_dir"):
        return load_asset(s)
    if c.kind == "member":
        key = f"{s} g{procedural.GENERATOR_VERSION} v{LABELLING_VERSION}".encode()
        return cached_asset(key, s, lambda: label_container(s), cache_dir)
    if c.kind == "cloud_file":
        from pour_gym.mesh.reconstruct import RECONSTRUCTION_VERSION

        key = p.read_bytes() + f"cloud r{RECONSTRUCTION_VERSION} v{LABELLING_VERSION}".encode()
        return cached_asset(key, p.stem, lambda: label_point_cloud(p), cache_dir)
    key = p.read_bytes() + f"v{LABELLING_VERSION}".encode()  # a mesh file
    return cached_asset(key, p.stem, lambda: label_container(s), cache_dir)
