"""The catalogue's containers by name, the splits, and what kind of name a container is.

The thesis's nine objects (:mod:`pour_gym.objects.catalogue`), the mug that ships with
``pybullet_data`` and two YCB scans (``REAL_MESHES``), each with a labelled asset folder
under :func:`asset_root`; ``SPLITS`` names groups of them. :func:`parse_container` is the
one parser of a single container's name (catalogue, procedural member, asset folder, mesh
or point cloud file) into a tagged :class:`ContainerSpec`; every entry point reaches it
through :func:`pour_gym.assets.containers.expand_containers` or the resolvers.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

from pour_gym.errors import InputError
from pour_gym.mesh.fileio import CLOUD_SUFFIXES, MESH_SUFFIXES, is_point_cloud_file
from pour_gym.objects import procedural
from pour_gym.objects.catalogue import OBJECT_NAMES

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


# Containers by split, for environments: the thesis trained on the red cup alone and
# tested on its other eight objects.
SPLITS: dict[str, tuple[str, ...]] = {
    "train": ("red_cup",),
    "test": tuple(n for n in OBJECT_NAMES if n != "red_cup"),
    "all": tuple(OBJECT_NAMES),
    "real": (PYBULLET_MUG, *REAL_MESHES),
}


# What parse_container tells apart.
CONTAINER_KINDS = ("catalogue", "member", "asset_dir", "mesh_file", "cloud_file")


@dataclass(frozen=True)
class ContainerSpec:
    """One container as named, and what kind of name it is.

    Attributes:
        text: the name as given (a catalogue name, ``procedural:test#7``, a path).
        kind: one of ``CONTAINER_KINDS``: a catalogue container (packaged asset), a
            procedural member (built and labelled on first use), an asset folder, a mesh
            file or a point cloud file (labelled, a cloud reconstructed first, on first
            use).
    """

    text: str
    kind: str

    @property
    def path(self) -> Path:
        """The name as a path (asset folders and files)."""
        return Path(self.text)


def _not_a_container(text: str) -> InputError:
    return InputError(
        f"{text!r} is not a container: use a split ({', '.join(SPLITS)}), a procedural "
        f"family (procedural:train, procedural:test, procedural:N@SEED), a catalogue "
        f"name ({', '.join(CATALOGUE)}), an asset directory, a mesh file "
        f"({', '.join(MESH_SUFFIXES)}) or a point cloud file ({', '.join(CLOUD_SUFFIXES)})"
    )


def parse_container(item: str | Path | ContainerSpec) -> ContainerSpec:
    """What kind of container a name is: the one parser every entry point uses.

    Args:
        item: a catalogue name, a procedural member, an asset folder, a mesh file or a
            point cloud file (a split, a family or a list: :func:`expand_containers`).

    Raises:
        InputError: none of those, naming what is accepted (or what is wrong with a
            procedural member's name).
    """
    if isinstance(item, ContainerSpec):
        return item
    text = str(item)
    if text in CATALOGUE:
        return ContainerSpec(text, "catalogue")
    path = Path(text)
    if path.is_dir():
        return ContainerSpec(text, "asset_dir")
    if path.is_file():
        if is_point_cloud_file(path):
            return ContainerSpec(text, "cloud_file")
        if path.suffix.lower() in MESH_SUFFIXES:
            return ContainerSpec(text, "mesh_file")
        raise _not_a_container(text)
    if text.startswith(procedural.PREFIX):
        procedural.member_spec(text)  # an InputError naming what is wrong with it
        return ContainerSpec(text, "member")
    if path.suffix.lower() in (*MESH_SUFFIXES, *CLOUD_SUFFIXES):
        raise InputError(f"no file {text!r} (from {Path.cwd()}): check the path")
    raise _not_a_container(text)
