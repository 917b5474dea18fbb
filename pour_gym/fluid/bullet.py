"""The reference fluid: particles as pybullet rigid spheres.

The same interface as :class:`pour_gym.fluid.pbf.PBFluid` (``x``, ``v``, ``count``,
``add``, ``remove``, ``add_collider``, ``step``), for cross-checking the position-based
fluid on small particle counts. Spheres of the particle spacing's diameter collide with
the containers' triangle meshes (static concave bodies posed kinematically at every
substep) and with the table. Like the SPH extension of bullet the thesis used, this fluid
has no pressure: it behaves like marbles, which is what the cross-check is for.

The containers collide as compounds of convex pieces (pybullet's V-HACD decomposition,
cached on disk): spheres pressed against a bare triangle mesh sink through its one-sided
surfaces (deeper than a wall is thick: most of a pour's spheres were lost), while a convex
piece pushes them back out of its volume.

The sphere world is tuned as bullet3's own many-spheres examples are: a contact breaking
threshold of a fraction of the sphere radius (the 0.02 m default makes every sphere keep
contacts with all spheres within 2 cm, which makes a pile of a thousand 20 times slower).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pybullet

from pour_gym.fluid.colliders import PosedCollider, substep_poses
from pour_gym.fluid.pbf import GRAVITY, MAX_SPEED, PBFConfig
from pour_gym.io.stdio import redirect_stdout_fd

if TYPE_CHECKING:
    import trimesh


def convex_parts(client, mesh: trimesh.Trimesh, cache_dir: str | Path) -> Path:
    """A V-HACD convex decomposition of a mesh as an OBJ file (cached by the mesh's hash).

    Args:
        client: a pybullet client (V-HACD runs inside pybullet).
        mesh: the container, in m.
        cache_dir: folder for ``vhacd_<hash>.obj``.

    Returns:
        The OBJ file, one object per convex piece, for ``createCollisionShape(fileName=)``.
    """
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    out = Path(cache_dir) / f"vhacd_{h.hexdigest()[:16]}.obj"
    if not out.is_file():
        out.parent.mkdir(parents=True, exist_ok=True)
        source = out.with_suffix(".in.obj")
        mesh.export(source)
        # Fine voxels and a low concavity keep thin walls as their own pieces. V-HACD
        # reports its progress on stdout, from C: discarded, or a command's table or JSON
        # would begin with it.
        with redirect_stdout_fd():
            client.vhacd(
                str(source),
                str(out),
                str(out.with_suffix(".log")),
                resolution=200000,
                concavity=0.0005,
                maxNumVerticesPerCH=64,
                planeDownsampling=2,
                convexhullDownsampling=2,
            )
        source.unlink()
    return out


@dataclass(eq=False, kw_only=True)
class BodyCollider(PosedCollider):
    """A container body the spheres collide with."""

    body: int


class BulletFluid:
    """Particles as rigid spheres in a pybullet client.

    Args:
        client: the world's pybullet client (a ``BulletClient``).
        positions: (N, 3) initial positions, m.
        config: fluid parameters (``spacing``, ``rest_density`` and ``substep`` are used).
        friction: sphere friction coefficient.
    """

    def __init__(
        self,
        client,
        positions: np.ndarray,
        config: PBFConfig | None = None,
        friction: float = 0.1,
    ):
        self.config = cfg = config or PBFConfig()
        self.client = client
        self.friction = friction
        self.colliders: list[BodyCollider] = []
        self.bodies: list[int] = []
        client.setGravity(*GRAVITY)
        client.setPhysicsEngineParameter(
            fixedTimeStep=cfg.substep, contactBreakingThreshold=0.2 * cfg.radius
        )
        self._shape = client.createCollisionShape(pybullet.GEOM_SPHERE, radius=cfg.radius)
        self._mass = cfg.rest_density * cfg.particle_volume
        self._x: np.ndarray | None = None
        self.time = 0.0
        self.add(positions)

    @property
    def count(self) -> int:
        """Number of particles."""
        return len(self.bodies)

    @property
    def x(self) -> np.ndarray:
        """(N, 3) positions, m."""
        if self._x is None:
            get = self.client.getBasePositionAndOrientation
            self._x = np.array([get(b)[0] for b in self.bodies], dtype=np.float64).reshape(-1, 3)
        return self._x

    @property
    def v(self) -> np.ndarray:
        """(N, 3) velocities, m/s."""
        get = self.client.getBaseVelocity
        return np.array([get(b)[0] for b in self.bodies], dtype=np.float64).reshape(-1, 3)

    def add(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Add spheres; returns their indices (appended at the end)."""
        p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        if not np.isfinite(p).all():
            raise ValueError("particle positions must be finite")
        n = self.count
        for k, xyz in enumerate(p):
            b = self.client.createMultiBody(
                baseMass=self._mass,
                baseCollisionShapeIndex=self._shape,
                basePosition=xyz.tolist(),
                useMaximalCoordinates=True,
            )
            self.client.changeDynamics(
                b, -1, lateralFriction=self.friction, restitution=0.0, linearDamping=0.0
            )
            if velocities is not None:
                self.client.resetBaseVelocity(b, np.asarray(velocities[k], float).tolist())
            self.bodies.append(b)
        self._x = None
        return np.arange(n, n + len(p))

    def remove(self, mask: np.ndarray) -> None:
        """Remove the spheres where ``mask`` is true; the others keep their order."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.count,):
            raise ValueError(f"mask of shape {mask.shape} for {self.count} particles")
        for b, drop in zip(self.bodies, mask, strict=True):
            if drop:
                self.client.removeBody(b)
        self.bodies = [b for b, drop in zip(self.bodies, mask, strict=True) if not drop]
        self._x = None

    def add_collider(self, body: int, rotation=None, translation=None) -> BodyCollider:
        """Register a container body; its pose is set through the returned collider."""
        c = BodyCollider.placed(rotation, translation, body=body)
        self.colliders.append(c)
        return c

    def step(self, dt: float) -> int:
        """Advance by ``dt`` seconds in fixed substeps; returns the substeps taken.

        Raises:
            FloatingPointError: a sphere's position became NaN or it flies off.
        """
        n_sub = max(round(dt / self.config.substep), 1) if dt > 0 else 0
        for c in self.colliders:
            if c.prev_rotation is None:
                c.prev_rotation, c.prev_translation = c.rotation.copy(), c.translation.copy()
        # Imported here: only this reference backend needs SciPy's rotations.
        from scipy.spatial.transform import Rotation

        poses = [substep_poses(c, n_sub) for c in self.colliders]
        for s in range(n_sub):
            for c, (rot, trans) in zip(self.colliders, poses, strict=True):
                quat = Rotation.from_matrix(rot[s + 1]).as_quat().tolist()
                self.client.resetBasePositionAndOrientation(c.body, trans[s + 1].tolist(), quat)
            self.client.stepSimulation()
        for c in self.colliders:
            c.prev_rotation, c.prev_translation = c.rotation.copy(), c.translation.copy()
        self._x = None
        x = self.x
        if not np.isfinite(x).all():
            raise FloatingPointError("the sphere fluid diverged: a position is NaN or infinite")
        if self.count and np.abs(self.v).max() > MAX_SPEED:
            raise FloatingPointError(f"the sphere fluid diverged: a sphere exceeds {MAX_SPEED} m/s")
        self.time += dt
        return n_sub
