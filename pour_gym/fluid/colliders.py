"""The containers a fluid collides with: posed signed-distance fields, and their motion.

A collider is a container's field (:class:`~pour_gym.fluid.sdf.SignedDistanceField`, in
the mesh's frame) at a pose, world = R q + t, with the pose it had at the end of the last
step: the fluid moves it from there to its current pose over the next step, linearly in
position and by slerp in rotation. Units are SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pour_gym.fluid.sdf import SignedDistanceField


def quaternion(rotation: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a 3x3 rotation matrix (Shepperd's method)."""
    m = np.asarray(rotation, dtype=np.float64)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0.0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q)


def substep_poses(collider: PosedCollider, n_sub: int) -> tuple[np.ndarray, np.ndarray]:
    """The collider's poses at ``n_sub + 1`` evenly spaced boundaries of a step.

    From its previous pose to its current one: rotations (n_sub + 1, 3, 3) by slerp,
    translations (n_sub + 1, 3) linearly (the fixed-substep bullet backend uses these).
    """
    r0, r1 = collider.prev_rotation, collider.rotation
    t0, t1 = collider.prev_translation, collider.translation
    from pour_gym.fluid.kernel import _pose_at  # the compiled kernel's, on first use

    q0, q1 = quaternion(r0), quaternion(r1)
    rot = np.empty((n_sub + 1, 3, 3))
    trans = np.empty((n_sub + 1, 3))
    for s, f in enumerate(np.linspace(0.0, 1.0, n_sub + 1)):
        _pose_at(q0, q1, r0, r1, t0, t1, float(f), rot[s], trans[s])
    return rot, trans


def wall_distance(
    points: np.ndarray, sdf: SignedDistanceField, rotation: np.ndarray, translation: np.ndarray
) -> np.ndarray:
    """Signed distance (N,) of world points to a posed container's material, m."""
    from pour_gym.fluid.kernel import _wall_distance  # compiled on first use

    out = np.full(len(points), np.inf)
    nx, ny, nz = sdf.values.shape
    _wall_distance(
        np.ascontiguousarray(points, dtype=np.float64),
        out,
        sdf.flat,
        nx,
        ny,
        nz,
        np.ascontiguousarray(sdf.origin, dtype=np.float64),
        float(sdf.spacing),
        np.ascontiguousarray(rotation, dtype=np.float64),
        np.ascontiguousarray(translation, dtype=np.float64),
    )
    return out


# eq=False: colliders are compared by identity; two may be equal in every field.
@dataclass(eq=False, kw_only=True)
class PosedCollider:
    """A container a fluid collides with, at its pose (world = R q + t).

    ``prev_*`` is the pose at the end of the last step; the fluid moves the container from
    there to ``rotation``, ``translation`` over the next step.
    """

    rotation: np.ndarray
    translation: np.ndarray
    prev_rotation: np.ndarray | None = None
    prev_translation: np.ndarray | None = None
    # (the rotation it was computed for, its quaternion): spares the fluid recomputing it.
    prev_quaternion: tuple | None = None

    @classmethod
    def placed(cls, rotation=None, translation=None, **handle):
        """A collider at a pose (identity and origin when not given)."""
        return cls(
            rotation=np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64),
            translation=np.zeros(3)
            if translation is None
            else np.asarray(translation, dtype=np.float64),
            **handle,
        )


@dataclass(eq=False, kw_only=True)
class Collider(PosedCollider):
    """A container the PBF fluid collides with through its signed-distance field."""

    sdf: SignedDistanceField


def collider_travel(collider: PosedCollider, field: SignedDistanceField) -> float:
    """Farthest any point of the collider's field moves from its previous pose, m."""
    if np.array_equal(collider.rotation, collider.prev_rotation) and np.array_equal(
        collider.translation, collider.prev_translation
    ):
        return 0.0  # a container standing still (the target, most of the time)
    corners = field.corners
    before = corners @ collider.prev_rotation.T + collider.prev_translation
    after = corners @ collider.rotation.T + collider.translation
    return float(np.linalg.norm(after - before, axis=1).max())
