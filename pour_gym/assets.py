"""Where packaged asset files live: one place that resolves their paths.

The top-level ``assets/`` folder of the repository is installed as the package
``pour_gym.asset_files``, so the same code finds it in a checkout and after ``pip install``.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from pour_gym.errors import InputError

REAL_MESHES: dict[str, str] = {
    "ycb_mug": "ycb/025_mug.obj",
    "ycb_bowl": "ycb/024_bowl.obj",
}


def asset_root() -> Path:
    """The folder of the packaged asset files."""
    return Path(str(files("pour_gym.asset_files")))


def real_mesh_path(name: str) -> Path:
    """Path of a packaged real scanned mesh.

    Args:
        name: one of :data:`REAL_MESHES` (``ycb_mug``, ``ycb_bowl``).

    Returns:
        The mesh file (metres, z up, centred on its bounding box; not watertight).

    Raises:
        InputError: unknown name.
    """
    try:
        return asset_root() / REAL_MESHES[name]
    except KeyError:
        raise InputError(
            f"unknown real mesh {name!r}; packaged ones: {', '.join(REAL_MESHES)}"
        ) from None
