"""A mesh as plain arrays, for the stages that only read it.

An environment's containers come from their asset folders and caches; stepping them needs
a mesh's vertices and faces, its bounds and whether it is one closed body (which decides
how its signed-distance field is signed), never trimesh's algorithms. :class:`Surface`
carries exactly those, so that an environment's process does not import trimesh (some 40
MB of resident memory with what it pulls in) until something draws or measures a mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import trimesh


@dataclass(frozen=True, eq=False)
class Surface:
    """A triangle mesh's arrays and the topology facts a signed-distance field needs.

    Reads like the part of :class:`trimesh.Trimesh` it stands for (``vertices``,
    ``faces``, ``bounds``, ``is_watertight``, ``body_count``), so the functions that take
    a mesh only to read those take a :class:`Surface` too.

    Attributes:
        vertices: (V, 3) float64, in m.
        faces: (F, 3) int64 vertex indices.
        bounds: (2, 3) lowest and highest corner of the vertices the faces use, in m.
        is_watertight: every edge shared by exactly two faces, consistently wound.
        body_count: connected pieces.
    """

    vertices: np.ndarray
    faces: np.ndarray
    bounds: np.ndarray
    is_watertight: bool
    body_count: int

    @classmethod
    def of(cls, mesh: trimesh.Trimesh) -> Surface:
        """The arrays and topology of a trimesh (its own numbers: bounds as trimesh's)."""
        return cls(
            vertices=np.asarray(mesh.vertices, dtype=np.float64),
            faces=np.asarray(mesh.faces, dtype=np.int64),
            bounds=np.asarray(mesh.bounds, dtype=np.float64),
            is_watertight=bool(mesh.is_watertight),
            body_count=int(mesh.body_count),
        )

    def to_trimesh(self) -> trimesh.Trimesh:
        """The mesh as a trimesh (vertices and faces as they are: nothing merged)."""
        import trimesh

        return trimesh.Trimesh(self.vertices.copy(), self.faces.copy(), process=False)
