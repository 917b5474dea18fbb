"""The folder where computed files are kept between runs (fields, labels of user meshes).

``$POUR_GYM_CACHE`` if set, else ``$XDG_CACHE_HOME/pour-gym``, else ``~/.cache/pour-gym``.
Everything in it can be deleted; it is recomputed when needed.
"""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir(kind: str) -> Path:
    """The cache folder for one kind of file (created).

    Args:
        kind: a sub-folder name, e.g. ``"sdf"``.
    """
    root = os.environ.get("POUR_GYM_CACHE")
    if root is None:
        base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
        root = str(Path(base) / "pour-gym")
    path = Path(root) / kind
    path.mkdir(parents=True, exist_ok=True)
    return path
