"""Parametric, watertight meshes of containers with ground-truth part labels.

A container is a solid of revolution: a closed cross-section in the (r, z) half-plane,
made of the base, the outer wall, a lip (round, flat or rolled) and the inner wall,
revolved about the z axis. The inner wall is the curve ``r(s) = a + (b - a) s^p + bulge
sin(pi s)`` and the outer wall is that curve offset by the wall thickness along its
normal, so the wall is equally thick everywhere. A square bowl or an oval scales each ring
by a superellipse. A cup gets a D-shaped tube as handle, joined to the body by a boolean
union (manifold3d), so the result stays one watertight solid.

For a thesis object the radii ``a`` (bottom of the cavity) and ``b`` (top of the inner
wall) and the height of the lip are solved so that the mesh has the thesis's real height,
rim radius and volume: height is the lip's top above the base, rim radius the mean
distance of the rim vertices to their centre, volume what the cavity holds up to the top
of the lip. The volume is computed exactly for the faceted mesh (each slab between two
rings is a frustum of a polygon). The procedural family
(:mod:`pour_gym.objects.procedural`) gives them directly.

Units are metres; z is up and the base rests on z = 0; the handle points along +x.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import trimesh
from scipy.optimize import brentq
from scipy.spatial import cKDTree

from pour_gym.errors import InputError
from pour_gym.objects.catalogue import ObjectSpec, get_spec
from pour_gym.parts import Part

if TYPE_CHECKING:
    from pour_gym.objects.procedural import ProceduralSpec

# Angular resolution of the rings and spacing of profile points along the cross-section:
# about 10k vertices per cup, close to the thesis's marching-cubes meshes.
N_THETA = 96
PROFILE_STEP = 0.002  # m
LIP_POINTS = 9  # odd, so that the top of the lip is a ring of the mesh
HANDLE_TUBE_RADIUS = 0.0045  # m
HANDLE_REACH = 0.026  # m, how far the handle stands off the wall
HANDLE_SPAN = (0.30, 0.80)  # lower and upper attachment, as fractions of the height
HANDLE_SIDES = 20


@dataclass(frozen=True)
class Shape:
    """What the builder reads of a container: wall, base, profile, cross-section, lip, handle.

    :func:`shape_of` reads one from a thesis object's
    :class:`~pour_gym.objects.catalogue.ObjectSpec` or from a procedural member's
    parameters (:mod:`pour_gym.objects.procedural`). Lengths in m.

    Attributes:
        name: the container's name (in error messages).
        height: the lip's top above the base.
        wall: wall thickness, along the wall's normal.
        base: thickness of the base (at least the wall's).
        flare: exponent p of the inner wall ``r(s) = a + (b - a) s^p + bulge sin(pi s)``
            over the normalised height s (1: a straight taper; below 1: a bowl).
        bulge: the belly added halfway up the inner wall.
        squareness: exponent n of the superellipse ``|x|^n + |y / aspect|^n = 1`` of the
            cross-section, or None for an ellipse (a circle when ``aspect`` is 1).
        aspect: the cross-section's y semi-axis over its x semi-axis (1: round).
        lip: ``"round"`` (a half circle across the wall), ``"flat"`` (cut square) or
            ``"rolled"`` (a bead that stands out of the wall by ``bead``).
        bead: how far a rolled lip stands out, m.
        handle: whether there is a handle (a D-shaped tube along +x).
        handle_span: its lower and upper attachment, as fractions of the height.
        handle_reach: how far it stands off the wall.
    """

    name: str
    height: float
    wall: float
    base: float
    flare: float = 1.0
    bulge: float = 0.0
    squareness: float | None = None
    aspect: float = 1.0
    lip: str = "round"
    bead: float = 0.0
    handle: bool = False
    handle_span: tuple[float, float] = HANDLE_SPAN
    handle_reach: float = HANDLE_REACH

    def ring_scale(self, n_theta: int = N_THETA) -> np.ndarray:
        """Radial scale of each of the ``n_theta`` rings of the mesh (:func:`ring_scale`)."""
        return ring_scale(self.squareness, n_theta, self.aspect)


def shape_of(spec: ObjectSpec | ProceduralSpec) -> Shape:
    """The builder's :class:`Shape` of a spec: the attributes it shares with a shape.

    A thesis object has no bulge, oval, lip or handle placement of its own: those keep
    the defaults (the thesis objects' shapes).
    """
    shared = [f.name for f in dataclasses.fields(Shape) if hasattr(spec, f.name)]
    return Shape(**{name: getattr(spec, name) for name in shared})


@dataclass
class Profile:
    """The closed cross-section of a container in the (r, z) half-plane.

    Attributes:
        points: (P, 2) array of (r, z) in m, from the base centre, along the base and the
            outer wall, over the lip, down the inner wall to the centre of the cavity floor.
            The first and last points lie on the axis (r = 0).
        labels: (P,) part of each point.
        cavity: (C, 2) polyline of (r, z) from the floor centre up the inner wall and the
            inner half of the lip to its top: the boundary of what the container holds.
        outer: (Q, 2) polyline of (r, z) of the outer wall, from the base up to the lip,
            with z increasing.
    """

    points: np.ndarray
    labels: np.ndarray
    cavity: np.ndarray
    outer: np.ndarray


@dataclass
class ContainerModel:
    """A built container: its mesh, per-vertex ground-truth labels and exact geometry.

    Attributes:
        spec: what it was built from: a thesis object's catalogue entry, or a procedural
            family member's :class:`~pour_gym.objects.procedural.ProceduralSpec`.
        mesh: the watertight solid, in m, base on z = 0.
        labels: (V,) int8 part of each vertex of ``mesh`` (see :class:`pour_gym.parts.Part`).
        cavity_volume: what the container holds up to the top of its lip, in m^3, exact for
            the faceted mesh.
        profile: the cross-section the mesh was revolved from.
        ring_scale: (N_THETA,) radial scale of each ring (all ones for a round container).
    """

    spec: ObjectSpec | ProceduralSpec
    mesh: trimesh.Trimesh
    labels: np.ndarray
    cavity_volume: float
    profile: Profile
    ring_scale: np.ndarray

    def cavity_mesh(self) -> trimesh.Trimesh:
        """The closed surface of the cavity: inner wall and floor plus a lid at the lip's top.

        Its volume is what the container holds; tests use it to check
        :attr:`cavity_volume` independently.
        """
        return _revolve(self.profile.cavity, self.ring_scale, close_top=True)


def superellipse_scale(
    theta: np.ndarray, squareness: float | None, aspect: float = 1.0
) -> np.ndarray:
    """Radial scale of the superellipse ``|x|^n + |y / aspect|^n = 1`` at the angles ``theta``.

    Args:
        theta: angles about the z axis, in rad.
        squareness: the exponent n, or ``None`` for an ellipse (n = 2).
        aspect: the y semi-axis over the x semi-axis.

    Returns:
        Scale factors of the same shape as ``theta``, all 1 for a circle.
    """
    theta = np.asarray(theta, dtype=float)
    if squareness is None and aspect == 1.0:
        return np.ones_like(theta)
    n = 2.0 if squareness is None else squareness
    c, s = np.abs(np.cos(theta)), np.abs(np.sin(theta))
    if aspect != 1.0:
        s = s / aspect
    return (c**n + s**n) ** (-1.0 / n)


def ring_scale(squareness: float | None, n_theta: int = N_THETA, aspect: float = 1.0) -> np.ndarray:
    """Radial scale of each of the ``n_theta`` rings of the mesh."""
    theta = np.linspace(0.0, 2.0 * np.pi, n_theta, endpoint=False)
    return superellipse_scale(theta, squareness, aspect)


def _resample(curve: np.ndarray, step: float) -> np.ndarray:
    """Resample a dense polyline to points about ``step`` apart along its length."""
    seg = np.linalg.norm(np.diff(curve, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(2, int(np.ceil(arc[-1] / step)) + 1)
    t = np.linspace(0.0, arc[-1], n)
    return np.column_stack([np.interp(t, arc, curve[:, 0]), np.interp(t, arc, curve[:, 1])])


def _segment(p0: tuple[float, float], p1: tuple[float, float], step: float) -> np.ndarray:
    """Points from p0 to p1 (both included) about ``step`` apart."""
    n = max(2, int(np.ceil(np.hypot(p1[0] - p0[0], p1[1] - p0[1]) / step)) + 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    return (1.0 - t) * np.asarray(p0) + t * np.asarray(p1)


def _inner_wall(
    a: float, b: float, z0: float, z1: float, flare: float, bulge: float = 0.0
) -> tuple[np.ndarray, ...]:
    """Dense inner wall curve and its outward unit normals in the (r, z) plane."""
    # s = u^2 resolves the steep start of a bowl's profile (flare < 1) without a kink.
    u = np.linspace(0.0, 1.0, 2001)
    s = u**2
    r = a + (b - a) * s**flare
    if bulge:
        r = r + bulge * np.sin(np.pi * s)
    curve = np.column_stack([r, z0 + s * (z1 - z0)])
    tangent = np.gradient(curve, u, axis=0)
    # At u = 0 the derivative in u vanishes; the direction of the first chord serves.
    tangent[0] = curve[1] - curve[0]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])  # points to +r / -z
    return curve, normal


def _lip(o_top: np.ndarray, i_top: np.ndarray, shape: Shape) -> np.ndarray:
    """The lip's (r, z) points from the outer wall's top over to the inner wall's top."""
    mid = 0.5 * (o_top + i_top)
    rho = 0.5 * np.linalg.norm(i_top - o_top)
    d = (i_top - o_top) / (2.0 * rho)
    up = np.array([-d[1], d[0]])
    if up[1] < 0.0:
        up = -up
    phi = np.linspace(0.0, np.pi, LIP_POINTS)
    if shape.lip == "round":
        return mid - rho * np.cos(phi)[:, None] * d + rho * np.sin(phi)[:, None] * up
    if shape.lip == "flat":
        return _segment(tuple(o_top), tuple(i_top), 2.0 * rho / (LIP_POINTS - 1))
    if shape.lip == "rolled":
        # Half an ellipse through both tops that stands out of the wall (-d) by ``bead``
        # and above the round lip's top by as much: a bead thicker than the wall.
        out = (rho * np.cos(phi) + shape.bead * np.sin(phi))[:, None] * d
        return mid - out + (rho + shape.bead) * np.sin(phi)[:, None] * up
    raise InputError(f"{shape.name}: unknown lip {shape.lip!r}; use round, flat or rolled")


def _profile(shape: Shape, a: float, b: float, top: float) -> Profile:
    """Cross-section for cavity bottom radius a, inner-wall top radius b and height top."""
    t = shape.wall
    inner, normal = _inner_wall(a, b, shape.base, top, shape.flare, shape.bulge)
    outer_dense = inner + t * normal
    if outer_dense[0, 1] < 0.0:
        raise InputError(f"{shape.name}: the base ({shape.base} m) is thinner than the wall")
    inner_pts = _resample(inner, PROFILE_STEP)
    outer_pts = _resample(outer_dense, PROFILE_STEP)

    lip = _lip(outer_pts[-1], inner_pts[-1], shape)

    foot_r, foot_z = outer_pts[0]
    base = _segment((0.0, 0.0), (foot_r, 0.0), PROFILE_STEP)
    foot = _segment((foot_r, 0.0), (foot_r, foot_z), PROFILE_STEP)[1:-1]
    floor = _segment((a, shape.base), (0.0, shape.base), PROFILE_STEP)[1:]
    parts = [
        (base, Part.OUTSIDE),
        (foot, Part.OUTSIDE),
        (outer_pts[:-1], Part.OUTSIDE),
        (lip, Part.RIM),
        (inner_pts[::-1][1:], Part.CONTAINER),
        (floor, Part.CONTAINER),
    ]
    points = np.concatenate([p for p, _ in parts])
    labels = np.concatenate([np.full(len(p), int(lab), dtype=np.int8) for p, lab in parts])

    half = LIP_POINTS // 2
    cavity = np.concatenate([floor[::-1], inner_pts[1:], lip[::-1][1 : half + 1]])
    outer = np.concatenate([[[foot_r, 0.0]], outer_pts, lip[1 : half + 1]])
    return Profile(points=points, labels=labels, cavity=cavity, outer=outer)


def _polygon_area_factor(scale: np.ndarray) -> float:
    """Area of the ring polygon with unit radius: sum of 0.5 g_i g_(i+1) sin(dtheta)."""
    dtheta = 2.0 * np.pi / len(scale)
    return float(0.5 * np.sin(dtheta) * np.sum(scale * np.roll(scale, -1)))


def _cavity_volume(cavity: np.ndarray, scale: np.ndarray) -> float:
    """Exact volume of the faceted cavity: polygon frustums between consecutive rings."""
    r, z = cavity[:, 0], cavity[:, 1]
    dz = np.diff(z)
    slab = dz * (r[:-1] ** 2 + r[:-1] * r[1:] + r[1:] ** 2) / 3.0
    return _polygon_area_factor(scale) * float(np.sum(slab))


def _rim_stats(profile: Profile, scale: np.ndarray) -> tuple[float, float]:
    """Mean distance of the rim vertices to their centre, and the centre's height."""
    lip = profile.points[profile.labels == Part.RIM]
    cz = float(lip[:, 1].mean())
    dist = np.hypot(lip[:, 0][:, None] * scale[None, :], lip[:, 1][:, None] - cz)
    return float(dist.mean()), cz


def solve_profile(spec: ObjectSpec, scale: np.ndarray) -> tuple[Profile, float]:
    """Solve the free radii so the profile has the spec's height, rim radius and volume.

    Args:
        spec: the object.
        scale: ring scale factors from :func:`ring_scale`.

    Returns:
        The profile and its cavity volume in m^3.

    Raises:
        InputError: no cavity with a positive floor radius has the requested volume.
    """
    shape = shape_of(spec)
    b = spec.rim_radius / float(scale.mean()) - spec.wall / 2.0
    top = spec.height - spec.wall / 2.0
    profile = None
    for _ in range(6):  # the three conditions are nearly decoupled: a fixed point converges

        def volume_error(a: float, b: float = b, top: float = top) -> float:
            return _cavity_volume(_profile(shape, a, b, top).cavity, scale) - spec.volume

        lo, hi = 0.05 * b, 2.0 * b
        if volume_error(lo) > 0.0 or volume_error(hi) < 0.0:
            raise InputError(
                f"{spec.name}: no cavity of height {spec.height} m and rim radius "
                f"{spec.rim_radius} m holds {spec.volume} m^3 with flare {spec.flare}"
            )
        a = brentq(volume_error, lo, hi, xtol=1e-9)
        profile = _profile(shape, a, b, top)
        radius, _ = _rim_stats(profile, scale)
        apex = float(profile.points[:, 1].max())
        b += (spec.rim_radius - radius) / float(scale.mean())
        top += spec.height - apex
    assert profile is not None
    return profile, _cavity_volume(profile.cavity, scale)


def _revolve(curve: np.ndarray, scale: np.ndarray, close_top: bool = False) -> trimesh.Trimesh:
    """Revolve an (r, z) polyline about z into a closed mesh.

    The first point (and the last, unless ``close_top``) must lie on the axis; with
    ``close_top`` the last ring is closed by a flat lid.
    """
    n = len(scale)
    theta = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    cos, sin = np.cos(theta) * scale, np.sin(theta) * scale
    ring_pts = curve[1:] if close_top else curve[1:-1]
    rings = np.stack([np.column_stack([r * cos, r * sin, np.full(n, z)]) for r, z in ring_pts])
    # The end points are the poles on the axis; with close_top the last one is the lid centre.
    first = np.array([[0.0, 0.0, curve[0, 1]]])
    last = np.array([[0.0, 0.0, curve[-1, 1]]])
    vertices = np.concatenate([first, rings.reshape(-1, 3), last])
    n_rings = len(ring_pts)
    last_idx = len(vertices) - 1
    j = np.arange(n)
    jn = (j + 1) % n
    faces = [np.column_stack([np.zeros(n, int), 1 + jn, 1 + j])]
    for k in range(n_rings - 1):
        a0, a1 = 1 + k * n + j, 1 + k * n + jn
        b0, b1 = 1 + (k + 1) * n + j, 1 + (k + 1) * n + jn
        faces.append(np.column_stack([a0, a1, b1]))
        faces.append(np.column_stack([a0, b1, b0]))
    top = 1 + (n_rings - 1) * n
    faces.append(np.column_stack([np.full(n, last_idx), top + j, top + jn]))
    mesh = trimesh.Trimesh(vertices, np.concatenate(faces), process=False)
    mesh.fix_normals()
    return mesh


def _handle(shape: Shape, outer: np.ndarray) -> trimesh.Trimesh:
    """A D-shaped tube along +x whose ends sit in the middle of the wall."""
    lo, hi = (f * shape.height for f in shape.handle_span)
    r_at = np.interp([lo, hi], outer[:, 1], outer[:, 0])
    inset = shape.wall / 2.0
    start = np.array([r_at[1] - inset, hi])
    end = np.array([r_at[0] - inset, lo])
    stand = HANDLE_TUBE_RADIUS + 0.002
    p1 = np.array([r_at[1] + stand, hi])
    p2 = np.array([r_at[0] + stand, lo])
    # The bow leaves and meets the straight ends horizontally, so the tube has no kink.
    phi = np.linspace(0.5 * np.pi, -0.5 * np.pi, 41)
    w = (np.sin(phi) + 1.0) / 2.0
    bow = np.column_stack(
        [
            w * p1[0] + (1 - w) * p2[0] + shape.handle_reach * np.cos(phi),
            (hi + lo) / 2 + (hi - lo) / 2 * np.sin(phi),
        ]
    )
    path2d = np.concatenate(
        [
            _segment(tuple(start), tuple(p1), 0.003)[:-1],
            bow,
            _segment(tuple(p2), tuple(end), 0.003)[1:],
        ]
    )
    path = np.column_stack([path2d[:, 0], np.zeros(len(path2d)), path2d[:, 1]])
    tangent = np.gradient(path, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    y = np.array([0.0, 1.0, 0.0])
    normal = np.cross(tangent, y)
    psi = np.linspace(0.0, 2.0 * np.pi, HANDLE_SIDES, endpoint=False)
    ring = np.cos(psi)[None, :, None] * normal[:, None, :] + np.sin(psi)[None, :, None] * y
    verts = (path[:, None, :] + HANDLE_TUBE_RADIUS * ring).reshape(-1, 3)
    m, k = len(path), HANDLE_SIDES
    j = np.arange(k)
    jn = (j + 1) % k
    faces = []
    for i in range(m - 1):
        a0, a1, b0, b1 = i * k + j, i * k + jn, (i + 1) * k + j, (i + 1) * k + jn
        faces += [np.column_stack([a0, a1, b1]), np.column_stack([a0, b1, b0])]
    c0, c1 = len(verts), len(verts) + 1
    verts = np.concatenate([verts, path[:1], path[-1:]])
    faces.append(np.column_stack([np.full(k, c0), jn, j]))
    faces.append(np.column_stack([np.full(k, c1), (m - 1) * k + j, (m - 1) * k + jn]))
    tube = trimesh.Trimesh(verts, np.concatenate(faces), process=False)
    tube.fix_normals()
    return tube


def _label_vertices(vertices: np.ndarray, profile: Profile, shape: Shape) -> np.ndarray:
    """Ground-truth part of each vertex from its position relative to the profile."""
    theta = np.arctan2(vertices[:, 1], vertices[:, 0])
    scale = superellipse_scale(theta, shape.squareness, shape.aspect)
    r = np.hypot(vertices[:, 0], vertices[:, 1]) / scale
    z = vertices[:, 2]
    _, nearest = cKDTree(profile.points).query(np.column_stack([r, z]))
    labels = profile.labels[nearest].copy()
    if shape.handle:
        r_out = np.interp(z, profile.outer[:, 1], profile.outer[:, 0])
        labels[(r > r_out + 3e-4) & (z < profile.outer[-1, 1])] = Part.HANDLE
    return labels


def build_object(spec: ObjectSpec | str) -> ContainerModel:
    """Build the labelled mesh of a thesis object.

    Args:
        spec: a catalogue name (see :data:`pour_gym.objects.OBJECT_NAMES`) or a spec.

    Returns:
        The container model: watertight mesh in m with the base on z = 0, per-vertex labels
        and exact cavity volume.

    Raises:
        InputError: unknown name, or shape parameters that admit no such container.
    """
    if isinstance(spec, str):
        spec = get_spec(spec)
    shape = shape_of(spec)
    scale = shape.ring_scale()
    profile, volume = solve_profile(spec, scale)
    return assemble(spec, shape, profile, scale, volume)


def build_from_radii(
    spec: ObjectSpec | ProceduralSpec, shape: Shape, a: float, b: float, top: float
) -> ContainerModel:
    """Build a container whose radii and height are given rather than solved for.

    Args:
        spec: what it is made from (kept in the model).
        shape: its :class:`Shape`.
        a: the cavity floor's radius, m.
        b: the inner wall's radius at its top, m.
        top: the inner wall's top above the base, m (the lip rises above it).

    Raises:
        InputError: a base thinner than the wall, or an unknown lip.
    """
    scale = shape.ring_scale()
    profile = _profile(shape, a, b, top)
    return assemble(spec, shape, profile, scale, _cavity_volume(profile.cavity, scale))


def assemble(
    spec: ObjectSpec | ProceduralSpec,
    shape: Shape,
    profile: Profile,
    scale: np.ndarray,
    volume: float,
) -> ContainerModel:
    """Revolve a solved profile, join the handle, and label every vertex from construction.

    Args:
        spec: what the container was made from (kept in the model).
        shape: its :class:`Shape`.
        profile: its cross-section.
        scale: the rings' radial scale (:meth:`Shape.ring_scale`).
        volume: the cavity's volume, m^3.

    Raises:
        RuntimeError: the union with the handle left a mesh that is not watertight.
    """
    body = _revolve(profile.points, scale)
    if shape.handle:
        mesh = trimesh.boolean.union([body, _handle(shape, profile.outer)], engine="manifold")
    else:
        mesh = body
    if not mesh.is_watertight:
        raise RuntimeError(f"{shape.name}: the built mesh is not watertight")
    labels = _label_vertices(np.asarray(mesh.vertices), profile, shape)
    return ContainerModel(
        spec=spec,
        mesh=mesh,
        labels=labels.astype(np.int8),
        cavity_volume=volume,
        profile=profile,
        ring_scale=scale,
    )


def cylinder_cup(
    radius: float, height: float, wall: float = 0.004, base: float = 0.006, sections: int = 96
) -> trimesh.Trimesh:
    """An open cylindrical cup: the simplest container with closed-form answers.

    Args:
        radius: inner radius, in m.
        height: outer height, in m (the cavity is ``height - base`` deep).
        wall: wall thickness, in m.
        base: thickness of the base, in m.
        sections: sides of the polygonal cross-section.

    Returns:
        A watertight mesh standing on z = 0.
    """
    outer = trimesh.creation.cylinder(radius=radius + wall, height=height, sections=sections)
    outer.apply_translation([0.0, 0.0, height / 2.0])
    inner = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    inner.apply_translation([0.0, 0.0, height / 2.0 + base])
    return trimesh.boolean.difference([outer, inner], engine="manifold")
