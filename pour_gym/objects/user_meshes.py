"""Containers made the way users' meshes are made, for tests and the soak command.

The thesis objects are single watertight solids. Meshes from modelling tools and scans are
often not: a mug is a revolved body plus a handle piece pushed into its wall (two bodies,
the handle's open ends buried in the wall), walls are thin, and a scan may have its opening
capped. These builders make such meshes with known dimensions, so the suite can check that
labelling, the collision field and the environments hold up on them.
"""

from __future__ import annotations

import itertools

import numpy as np
import trimesh

from pour_gym.objects.build import cylinder_cup


def _dense(profile: np.ndarray, step: float = 0.002) -> np.ndarray:
    """A polyline (N, 2) with points added so that no segment is longer than ``step``.

    Meshes from modelling tools carry vertices all over their surfaces; a revolved profile
    of a few corners would have none between the rim and the base.
    """
    out = [profile[0]]
    for a, b in itertools.pairwise(profile):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out += [a + (b - a) * k / n for k in range(1, n + 1)]
    return np.array(out)


def _revolved_wall(
    radius: float, height: float, wall: float, base: float, sections: int
) -> trimesh.Trimesh:
    """A cup body as a revolved wall cross-section (one closed body), base on z = 0."""
    r_in, r_out = radius, radius + wall
    # The cross-section, counter-clockwise in (r, z): base, outer wall, rim, inner wall.
    profile = np.array(
        [
            [0.0, 0.0],
            [r_out, 0.0],
            [r_out, height],
            [r_in, height],
            [r_in, base],
            [0.0, base],
        ]
    )
    return trimesh.creation.revolve(_dense(profile), sections=sections)


def _tube(path: np.ndarray, radius: float, sides: int = 16) -> trimesh.Trimesh:
    """An open tube (no end caps) of circular section along a polyline (N, 3)."""
    rings = []
    for k, point in enumerate(path):
        ahead = path[min(k + 1, len(path) - 1)] - path[max(k - 1, 0)]
        t = ahead / np.linalg.norm(ahead)
        n = np.cross(t, [0.0, 1.0, 0.0])
        n /= np.linalg.norm(n)
        b = np.cross(t, n)
        a = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
        rings.append(point + radius * (np.outer(np.cos(a), n) + np.outer(np.sin(a), b)))
    vertices = np.concatenate(rings)
    faces = []
    for k in range(len(path) - 1):
        for j in range(sides):
            a, b = k * sides + j, k * sides + (j + 1) % sides
            c, d = a + sides, b + sides
            faces += [[a, b, d], [a, d, c]]
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


def two_body_mug(
    radius: float = 0.04,
    height: float = 0.095,
    wall: float = 0.005,
    base: float = 0.006,
    sections: int = 96,
) -> trimesh.Trimesh:
    """A mug as users model one: a revolved body and a handle tube overlapping its wall.

    Two bodies in one mesh, not watertight: the handle is an open tube (no end caps)
    whose ends are buried in the body's wall, as a handle pushed into a cup in a modelling
    tool is. Its inside and outside cannot be told by ray parity alone.

    Args:
        radius: inner radius, m.
        height: outer height, m.
        wall: wall thickness, m (5 mm: the mug that made Pour-v0 raise).
        base: base thickness, m.
        sections: sides of the revolved body.

    Returns:
        The mesh, base on z = 0, handle along +x.
    """
    body = _revolved_wall(radius, height, wall, base, sections)
    r_mid = radius + 0.5 * wall  # the handle's ends stop in the middle of the wall
    reach = 0.03  # how far the handle stands out from the wall, m
    a = np.linspace(-0.5 * np.pi, 0.5 * np.pi, 24)
    centre_z, span = 0.55 * height, 0.3 * height
    path = np.column_stack(
        [r_mid + (reach + 0.5 * wall) * np.cos(a), np.zeros_like(a), centre_z + span * np.sin(a)]
    )
    handle = _tube(path, 0.006)
    return trimesh.util.concatenate([body, handle])


def thin_walled_cup(
    radius: float = 0.035, height: float = 0.09, wall: float = 0.003, base: float = 0.004
) -> trimesh.Trimesh:
    """A straight cup with 3 mm walls (watertight), the thinnest the suite promises to hold."""
    return cylinder_cup(radius, height, wall, base)


def capped_cup(
    radius: float = 0.035, height: float = 0.09, dented_base: bool = False
) -> trimesh.Trimesh:
    """A cup whose opening a scan closed: a lid fused onto the rim (watertight, sealed).

    Args:
        radius: inner radius, m.
        height: outer height, m.
        dented_base: also hollow the base from below (a foot ring), so that the mesh turned
            upside down holds a little water in the dent, as the YCB pitcher's scan does.
    """
    cup = cylinder_cup(radius, height)
    lid = trimesh.creation.cylinder(radius=radius + 0.004, height=0.004)
    lid.apply_translation([0.0, 0.0, height - 0.002])
    sealed = trimesh.boolean.union([cup, lid], engine="manifold")
    if dented_base:
        dent = trimesh.creation.cylinder(radius=0.8 * radius, height=0.006)
        sealed = trimesh.boolean.difference([sealed, dent], engine="manifold")
    return sealed
