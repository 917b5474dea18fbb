"""A pybullet world with a table, containers and a particle fluid.

Each world owns its own pybullet client (``DIRECT``, never the global connection), so that
any number of worlds (one per environment, vectorised environments) run side by side.
Containers are bodies made from labelled assets; a held container is moved kinematically by
setting its pose before each step. The fluid (``"pbf"``: position-based fluid colliding
with the containers' signed-distance fields; ``"bullet"``: rigid spheres colliding with the
container bodies) is stepped with the containers moving smoothly from their pose at the
previous step to the new one.

After every step the world checks that no particle's centre lies inside a container's
material (:class:`~pour_gym.errors.SimulationError` otherwise) and that no position is NaN
(``FloatingPointError``); nothing is silently carried on.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet
from pybullet_utils.bullet_client import BulletClient

from pour_gym.assets import LabelledAsset, load_asset
from pour_gym.errors import InputError, SimulationError
from pour_gym.fluid.bullet import BodyCollider, BulletFluid, convex_parts
from pour_gym.fluid.colliders import Collider, quaternion, wall_distance
from pour_gym.fluid.pbf import PBFConfig, PBFluid
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf
from pour_gym.io.cache import cache_dir, mesh_key
from pour_gym.io.stdio import redirect_stdout_fd
from pour_gym.sim.camera import Camera, render
from pour_gym.sim.census import Census, take_census
from pour_gym.sim.raster import DRAWN_RADIUS
from pour_gym.sim.rotations import as_quaternion, quaternion_to_matrix
from pour_gym.sim.spawn import block, cavity_lattice, fill_lattice

FLUIDS = ("pbf", "bullet")
TABLE_COLOR = (0.72, 0.60, 0.45, 1.0)
CUP_COLORS = ((0.85, 0.20, 0.20, 1.0), (0.92, 0.92, 0.88, 1.0), (0.55, 0.75, 0.55, 1.0))
# Field resolution and extent: below half the thinnest wall (3.5 mm), and beyond the mesh
# by more than a particle's kernel.
SDF_SPACING = 1e-3
SDF_MARGIN = 0.012


def as_rotation(rotation) -> np.ndarray:
    """A (3, 3) rotation matrix from a matrix, an (x, y, z, w) quaternion or None."""
    if rotation is None:
        return np.eye(3)
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape == (4,):
        return quaternion_to_matrix(r)
    if r.shape != (3, 3):
        raise InputError(f"a rotation is a 3x3 matrix or an (x, y, z, w) quaternion, not {r.shape}")
    return r


def container_field(asset: LabelledAsset, cache: str | Path | None = None) -> SignedDistanceField:
    """The signed-distance field a world gives a container (computed once, then cached).

    Args:
        asset: the container.
        cache: folder of cached fields (default: the user cache).
    """
    return build_sdf(
        asset.surface, SDF_SPACING, SDF_MARGIN, cache_dir=cache if cache else cache_dir("sdf")
    )


def mesh_shapes(client, mesh, color, convex: Path | None = None, collide: bool = True):
    """A mesh's pybullet (collision, visual) shapes, for any number of bodies.

    Args:
        client: a pybullet client.
        mesh: the trimesh, in m, in the body's frame.
        color: RGBA.
        convex: an OBJ of convex pieces to collide as (see
            :func:`pour_gym.fluid.bullet.convex_parts`); the concave triangle mesh if None.
        collide: give the body a collision shape at all (the PBF fluid collides through
            fields, so its worlds skip the cost of building one).

    Returns:
        ``(collision shape or -1, visual shape)``.
    """
    verts = np.asarray(mesh.vertices, dtype=np.float64).tolist()
    faces = np.asarray(mesh.faces, dtype=np.int64).ravel().tolist()
    if not collide:
        shape = -1
    elif convex is not None:
        shape = client.createCollisionShape(pybullet.GEOM_MESH, fileName=str(convex))
    else:
        shape = client.createCollisionShape(
            pybullet.GEOM_MESH,
            vertices=verts,
            indices=faces,
            flags=pybullet.GEOM_FORCE_CONCAVE_TRIMESH,
        )
    visual = client.createVisualShape(
        pybullet.GEOM_MESH, vertices=verts, indices=faces, rgbaColor=color
    )
    return shape, visual


def mesh_body(
    client, mesh, position, rotation, color, convex: Path | None = None, collide: bool = True
) -> int:
    """A static pybullet body with the mesh as its visual (shapes as :func:`mesh_shapes`).

    Args:
        client: a pybullet client.
        mesh: the trimesh, in m, in the body's frame.
        position: (3,) body position, m.
        rotation: (3, 3) body rotation.
        color: RGBA.
        convex: convex pieces to collide as, or None (:func:`mesh_shapes`).
        collide: give the body a collision shape at all.

    Returns:
        The body's id; move it with ``resetBasePositionAndOrientation``.
    """
    shape, visual = mesh_shapes(client, mesh, color, convex, collide)
    quat = as_quaternion(rotation)
    return client.createMultiBody(0.0, shape, visual, np.asarray(position).tolist(), quat)


@dataclass(eq=False)  # identity: two containers may be equal in every field
class Container:
    """A container in the world.

    Attributes:
        index: its position in :attr:`World.containers` (and in a census).
        asset: the labelled asset (mesh and geometry in the container's frame).
        body: the pybullet body, or None while the world has no pybullet client (a PBF
            world makes its client and bodies when first asked for a picture).
        sdf: its signed-distance field, in its frame.
        collider: the fluid's handle on it; holds the current pose.
        color: RGBA for pictures.
        lattice: its cavity's fill lattice at the world's spacing (kept after the first
            fill, so that refilling every episode costs no recomputation).
    """

    index: int
    asset: LabelledAsset
    body: int | None
    sdf: SignedDistanceField
    collider: Collider | BodyCollider
    color: tuple[float, float, float, float] = CUP_COLORS[0]
    lattice: np.ndarray | None = None

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) rotation (world = R @ local + t)."""
        return self.collider.rotation

    @property
    def translation(self) -> np.ndarray:
        """(3,) position of the container's frame origin (its base), m."""
        return self.collider.translation

    def to_world(self, local: np.ndarray) -> np.ndarray:
        """Container-frame points (..., 3) in world coordinates."""
        return np.asarray(local) @ self.rotation.T + self.translation


class World:
    """A table, containers and a particle fluid in a pybullet client of their own.

    The PBF fluid collides through the containers' fields, not through pybullet, so a PBF
    world without ``solid`` makes its pybullet client only when something needs it (a
    picture, :attr:`client`): an environment that trains headless never pays for one (30
    MB and a body per container met). A container's pybullet shapes are made once per
    world and reused when it is placed again.

    Args:
        fluid: ``"pbf"`` or ``"bullet"``.
        config: fluid parameters (spacing, solver); the defaults look like water at cup
            scale.
        table: put a table (a plane at z = 0) under everything.
        sdf_cache: folder for the containers' fields and convex decompositions (default:
            the user cache).
        num_threads: threads of the PBF fluid (``None``: one per core this process may
            use, one in a worker process; see :func:`pour_gym.fluid.pbf.default_threads`).
        solid: give the containers' bodies collision shapes (V-HACD convex pieces, as the
            ``bullet`` fluid's) with the PBF fluid too, for worlds where something else
            collides with them (an arm); the PBF fluid itself collides through fields.
    """

    def __init__(
        self,
        fluid: str = "pbf",
        config: PBFConfig | None = None,
        table: bool = True,
        sdf_cache: str | Path | None = None,
        num_threads: int | None = None,
        solid: bool = False,
    ):
        if fluid not in FLUIDS:
            raise InputError(f"unknown fluid {fluid!r}; use one of {', '.join(FLUIDS)}")
        self.fluid_kind = fluid
        self.solid = bool(solid)
        self.config = config or PBFConfig()
        self.sdf_cache = Path(sdf_cache) if sdf_cache is not None else cache_dir("sdf")
        self._client: BulletClient | None = None
        # A container's (collision, visual) shapes by mesh and colour: made once per world.
        self._shapes: dict[tuple, tuple[int, int]] = {}
        self.containers: list[Container] = []
        self.table = table
        self.table_body: int | None = None  # the table's pybullet body (once there is a client)
        self._closed = False
        empty = np.empty((0, 3))
        floor = 0.0 if table else None
        self.fluid: PBFluid | BulletFluid
        if fluid == "pbf":
            self.fluid = PBFluid(empty, self.config, floor=floor, num_threads=num_threads)
            if self.solid:
                self.client  # noqa: B018 (something else collides with the bodies)
        else:
            self.fluid = BulletFluid(self.client, empty, self.config)

    def set_liquid(self, config: PBFConfig) -> None:
        """Take a liquid's fluid parameters (:meth:`pour_gym.fluid.liquid.Liquid.fluid_config`).

        Raises:
            InputError: a viscous liquid in a ``bullet`` world (rigid spheres have none).
        """
        if config == self.config:
            return
        if self.fluid_kind != "pbf":
            raise InputError("liquids other than water need fluid='pbf' (rigid spheres have no "
                             "viscosity)")  # fmt: skip
        self.fluid.set_viscosity(config)
        self.config = config

    @property
    def client(self) -> BulletClient:
        """The world's pybullet client, with the table and a body per container.

        Made at first use in a PBF world (the containers' bodies are then made where the
        containers are); from the start in a ``bullet`` or ``solid`` one.
        """
        if self._client is None:
            self._check_open()
            with redirect_stdout_fd():
                self._client = BulletClient(connection_mode=pybullet.DIRECT)
            self._client.setGravity(0.0, 0.0, -9.81)
            if self.table:
                shape = self._client.createCollisionShape(pybullet.GEOM_PLANE)
                visual = self._client.createVisualShape(
                    pybullet.GEOM_BOX,
                    halfExtents=[0.5, 0.5, 0.005],
                    rgbaColor=TABLE_COLOR,
                    visualFramePosition=[0.0, 0.0, -0.005],
                )
                self.table_body = self._client.createMultiBody(0.0, shape, visual)
            for c in self.containers:
                c.body = self._body(c.asset, c.translation, c.rotation, c.color)
        return self._client

    def _body(self, asset: LabelledAsset, position, rotation, color) -> int:
        """A pybullet body for a container (its shapes made once per world and colour)."""
        client = self.client
        bullet = isinstance(self.fluid, BulletFluid)
        collide = self.solid or bullet
        key = (mesh_key(asset.mesh), tuple(color), collide)
        if key not in self._shapes:
            convex = convex_parts(client, asset.mesh, self.sdf_cache) if collide else None
            self._shapes[key] = mesh_shapes(client, asset.mesh, color, convex, collide)
        shape, visual = self._shapes[key]
        quat = as_quaternion(rotation)
        body = client.createMultiBody(0.0, shape, visual, np.asarray(position).tolist(), quat)
        if bullet:
            client.changeDynamics(body, -1, lateralFriction=self.fluid.friction)
        return body

    # ------------------------------------------------------------------ containers
    def add_container(
        self,
        asset: LabelledAsset | str | Path,
        position=(0.0, 0.0, 0.0),
        rotation=None,
        color: tuple[float, float, float, float] | None = None,
        sdf: SignedDistanceField | None = None,
    ) -> Container:
        """Place a container.

        Args:
            asset: a labelled asset, or a catalogue name / asset directory to load one.
            position: (3,) where the container's frame origin (its base) goes, m.
            rotation: a 3x3 matrix or an (x, y, z, w) quaternion; upright if None.
            color: RGBA for pictures.
            sdf: the asset's field if already at hand (see :func:`container_field`).

        Returns:
            The container; move it with :meth:`set_pose`.
        """
        if not isinstance(asset, LabelledAsset):
            asset = load_asset(asset)
        if sdf is None:
            sdf = container_field(asset, self.sdf_cache)
        rot, pos = as_rotation(rotation), np.asarray(position, dtype=np.float64)
        color = color or CUP_COLORS[len(self.containers) % len(CUP_COLORS)]
        body = None if self._client is None else self._body(asset, pos, rot, color)
        if isinstance(self.fluid, PBFluid):
            collider = self.fluid.add_collider(sdf, rot, pos)
        else:
            collider = self.fluid.add_collider(body, rot, pos)
        c = Container(len(self.containers), asset, body, sdf, collider, color)
        self.containers.append(c)
        return c

    def remove_container(self, container: Container) -> None:
        """Take a container out of the world (the others are renumbered in order)."""
        if container.body is not None:
            self.client.removeBody(container.body)
        self.fluid.colliders.remove(container.collider)
        self.containers.remove(container)
        for k, c in enumerate(self.containers):
            c.index = k

    def set_pose(self, container: Container, position, rotation=None) -> None:
        """Where a container will be at the end of the next step (it moves there smoothly).

        Args:
            container: one of this world's containers.
            position: (3,) its frame origin, m.
            rotation: a 3x3 matrix or an (x, y, z, w) quaternion; upright if None.
        """
        pos = np.asarray(position, dtype=np.float64)
        if pos.shape != (3,) or not np.isfinite(pos).all():
            raise InputError(f"a container position is 3 finite numbers, got {position!r}")
        container.collider.rotation = as_rotation(rotation)
        container.collider.translation = pos

    def teleport(self, container: Container, position, rotation=None) -> None:
        """Put a container at a pose at once (no sweep through the fluid in between).

        For setting a scene up; during a simulation use :meth:`set_pose`, which moves the
        container smoothly over the next step.
        """
        self.set_pose(container, position, rotation)
        c = container.collider
        c.prev_rotation, c.prev_translation = c.rotation.copy(), c.translation.copy()
        if container.body is not None:
            quat = as_quaternion(c.rotation)
            self.client.resetBasePositionAndOrientation(
                container.body, c.translation.tolist(), quat
            )

    # ------------------------------------------------------------------ fluid
    @property
    def particles(self) -> np.ndarray:
        """(N, 3) particle positions, m."""
        return self.fluid.x

    @property
    def particle_volume(self) -> float:
        """Fluid volume per particle, m^3."""
        return self.config.particle_volume

    def add_particles(self, positions: np.ndarray, velocities=None) -> np.ndarray:
        """Add particles at world positions; returns their indices."""
        return self.fluid.add(positions, velocities)

    def remove_particles(self, mask: np.ndarray) -> None:
        """Remove the particles where ``mask`` is true (the others keep their order)."""
        self.fluid.remove(mask)

    def clear_particles(self) -> None:
        """Remove all particles."""
        self.fluid.remove(np.ones(self.fluid.count, dtype=bool))

    def spawn_block(self, low, high) -> np.ndarray:
        """Fill the box ``[low, high]`` (world, m) with particles; returns their indices."""
        return self.add_particles(block(low, high, self.config.spacing))

    def fill(
        self, container: Container, volume: float | None = None, particles: int | None = None
    ) -> np.ndarray:
        """Fill a container from its bottom with a volume (m^3) or a number of particles.

        The lattice is laid out in the container's frame and posed with it; the container
        should be upright. Returns the new particles' indices.
        """
        if (volume is None) == (particles is None):
            raise InputError("give the fill as a volume in m^3 or as a particle count, not both")
        count = round(volume / self.particle_volume) if volume is not None else particles
        if count < 0:
            raise InputError(f"a fill cannot be negative ({count} particles)")
        spacing = self.config.spacing
        if container.lattice is None:
            container.lattice = cavity_lattice(container.asset.geometry, container.sdf, spacing)
        local = fill_lattice(
            container.asset.geometry, container.sdf, spacing, count, container.lattice
        )
        return self.add_particles(container.to_world(local))

    # ------------------------------------------------------------------ time
    def step(self, dt: float) -> int:
        """Advance by ``dt`` seconds; returns the fluid substeps taken.

        Containers move smoothly to the poses last given to :meth:`set_pose`; the fluid
        takes as many substeps as the motion needs, and puts back particles that tunnelled
        into a wall (:attr:`corrections`). Nothing here checks the walls: that is
        :meth:`check_walls`, a validation for tests and ``pour-gym soak``.

        Raises:
            FloatingPointError: the fluid diverged.
        """
        self._check_open()
        n_sub = self.fluid.step(dt)
        if isinstance(self.fluid, PBFluid) and self._client is not None:
            # The bodies follow for rendering (the fluid collides with the fields). The
            # quaternion by Shepperd's method: a SciPy Rotation object costs more than the
            # rest of the step's bookkeeping.
            for c in self.containers:
                w, x, y, z = quaternion(c.rotation)
                self.client.resetBasePositionAndOrientation(
                    c.body, c.translation.tolist(), [x, y, z, w]
                )
        return n_sub

    @property
    def corrections(self) -> int:
        """Particles put back out of a wall they had tunnelled into during the last step."""
        return int(getattr(self.fluid, "corrections", 0))

    def check_walls(self) -> None:
        """Raise if a particle's centre lies in a container's material (a validation).

        Raises:
            SimulationError: naming the particle, the container and the depth.
        """
        x = self.fluid.x
        if not len(x) or not self.containers:
            return
        # PBF projects particles a radius out of the walls, one container after the other
        # (a push out of one can graze another by a hair). The spheres of the reference
        # backend collide with V-HACD convex pieces, which stray from the exact mesh by a
        # few tenths of a millimetre, and sink in by their contact softness: for them a
        # centre deeper than 1.25 sphere radii counts as inside a wall.
        r = self.config.radius
        tolerance = -0.25 * r if isinstance(self.fluid, PBFluid) else -1.25 * r
        for c in self.containers:
            d = wall_distance(x, c.sdf, c.rotation, c.translation)
            if d.min() < tolerance:
                k = int(np.argmin(d))
                raise SimulationError(
                    f"particle {k} at {x[k].round(4).tolist()} is {-d[k] * 1e3:.2f} mm inside "
                    f"the wall of container {c.index} ({c.asset.name}); the container moved "
                    "too fast for its wall thickness (slow it down or take smaller substeps)"
                )

    # ------------------------------------------------------------------ observation
    def census(self) -> Census:
        """Which container each particle is in (by the containers' cavities)."""
        return take_census(
            self.fluid.x,
            [c.asset.geometry for c in self.containers],
            [(c.rotation, c.translation) for c in self.containers],
        )

    def render(self, camera: Camera | None = None) -> np.ndarray:
        """An RGB picture (height, width, 3) uint8 of the world and its particles."""
        self._check_open()
        radius = DRAWN_RADIUS * self.config.spacing
        return render(self.client, camera or Camera(), self.fluid.x, radius)

    def close(self) -> None:
        """Disconnect the pybullet client; safe to call twice."""
        if not self._closed:
            if self._client is not None:
                self._client.disconnect()
                self._client = None
            self._closed = True

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this world was closed")

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass
