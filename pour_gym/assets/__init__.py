"""Labelled assets: the format, labelling, the catalogue, and the parser of a container.

- :mod:`pour_gym.assets.format`: the asset folder (mesh in the canonical frame, a part per
  vertex, meta), written and loaded (:class:`LabelledAsset`, :func:`write_asset`,
  :func:`load_asset`).
- :mod:`pour_gym.assets.labelling`: labelling a mesh or a point cloud by warping the red
  cup onto it (chapter 4), and caching what was labelled.
- :mod:`pour_gym.assets.catalogue`: the catalogue's containers, the splits, and the one
  parser of a container's name (:func:`parse_container`, a tagged :class:`ContainerSpec`).
- :mod:`pour_gym.assets.containers`: whatever ``objects=`` or a command takes, expanded
  (:func:`expand_containers`) and resolved into a labelled asset (:func:`resolve_asset`);
  a name resolved into a mesh to label: :func:`pour_gym.assets.labelling.resolve_target`.

The repository's top-level ``assets/`` folder is installed as the package
``pour_gym.asset_files``; :func:`asset_root` finds it in a checkout and after
``pip install``. ``pour-gym build-assets`` rebuilds every catalogue asset there.
"""

from pour_gym.assets.catalogue import (
    CATALOGUE,
    CONTAINER_KINDS,
    PYBULLET_MUG,
    REAL_MESHES,
    SPLITS,
    ContainerSpec,
    asset_root,
    parse_container,
    real_mesh_path,
)
from pour_gym.assets.containers import expand_containers, resolve_asset
from pour_gym.assets.format import (
    LabelledAsset,
    canonical_coordinates,
    canonical_transform,
    check_open,
    load_asset,
    write_asset,
)
from pour_gym.assets.labelling import (
    LABELLING_VERSION,
    cached_asset,
    label_container,
    label_point_cloud,
    part_iou,
    resolve_target,
)

__all__ = [
    "CATALOGUE",
    "CONTAINER_KINDS",
    "LABELLING_VERSION",
    "PYBULLET_MUG",
    "REAL_MESHES",
    "SPLITS",
    "ContainerSpec",
    "LabelledAsset",
    "asset_root",
    "cached_asset",
    "canonical_coordinates",
    "canonical_transform",
    "check_open",
    "expand_containers",
    "label_container",
    "label_point_cloud",
    "load_asset",
    "parse_container",
    "part_iou",
    "real_mesh_path",
    "resolve_asset",
    "resolve_target",
    "write_asset",
]
