"""The folder where computed files are kept between runs (fields, labels of user meshes).

``$POUR_GYM_CACHE`` if set, else ``$XDG_CACHE_HOME/pour-gym``, else ``~/.cache/pour-gym``.
Everything in it can be deleted; it is recomputed when needed.
"""

from __future__ import annotations

import hashlib
import os
import re
import threading
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # trimesh takes 0.6 s to import; the fluid's processes need none
    import trimesh


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


def write_npz(path: Path, *, compressed: bool = True, **arrays) -> None:
    """Write a cache entry's ``.npz`` whole under another name first, then rename it.

    Envs in other processes (a vector env's workers, a second run) or threads read the
    same entries: renamed into place, a reader never sees half a file.

    Args:
        path: the entry.
        compressed: ``np.savez_compressed`` (else ``np.savez``).
        **arrays: what the file holds, by name.
    """
    part = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.npz")
    (np.savez_compressed if compressed else np.savez)(part, **arrays)
    os.replace(part, path)


def mesh_key(mesh: trimesh.Trimesh, *params: float) -> str:
    """A short hash of a mesh's vertices and faces and of the parameters a result used.

    Cached files are named by it, so a changed mesh or parameter misses the cache.
    """
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    h.update(np.array(params, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def keyed_entry(key: bytes, stem: str, folder: str | Path | None = None) -> Path:
    """The path of a cached result with this key (it may not exist yet).

    Args:
        key: what the result is a function of (file bytes, names, versions, settings).
        stem: the start of its name, for people reading the cache.
        folder: where such results are kept (default: the user cache's ``assets``).
    """
    root = Path(folder) if folder is not None else cache_dir("assets")
    stem = re.sub(r"[^A-Za-z0-9]+", "_", stem)
    return root / f"{stem}_{hashlib.sha256(key).hexdigest()[:16]}"
