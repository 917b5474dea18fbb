"""Rotation matrices of the few kinds the environments build, equal to SciPy's bit for bit.

``scipy.spatial.transform.Rotation`` would import all of ``scipy.spatial`` (some 25 MB
of resident memory per process) for a turn about z at each reset. These functions follow
SciPy's own arithmetic (a unit quaternion, then its matrix, term by term), so that
episodes stay the bits they were with ``Rotation.from_euler("z", a).as_matrix()`` and
``Rotation.from_rotvec(v).as_matrix()``; ``tests/test_sim.py`` compares them on 10^5
angles.
"""

from __future__ import annotations

import math

import numpy as np


def quaternion_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    """The (3, 3) rotation matrix of a unit quaternion (x, y, z, w), as SciPy forms it."""
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array(
        [
            [x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
            [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
            [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2],
        ]
    )


def about_z(angle: float) -> np.ndarray:
    """A turn of ``angle`` radians about +z (SciPy's ``from_euler("z", angle)``)."""
    half = 0.5 * float(angle)
    return quaternion_matrix(0.0, 0.0, math.sin(half), math.cos(half))


def from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """The rotation of a rotation vector (axis times angle in radians; SciPy's ``from_rotvec``)."""
    x, y, z = (float(c) for c in np.asarray(rotvec, dtype=np.float64))
    angle = math.sqrt(x * x + y * y + z * z)
    if angle <= 1e-3:  # SciPy's Taylor series of sin(angle / 2) / angle near zero
        a2 = angle * angle
        scale = 0.5 - a2 / 48 + a2 * a2 / 3840
    else:
        scale = math.sin(angle / 2) / angle
    return quaternion_matrix(scale * x, scale * y, scale * z, math.cos(angle / 2))


def as_rotvec(rotation: np.ndarray) -> np.ndarray:
    """A (3, 3) rotation's rotation vector (axis times angle, rad): ``from_rotvec``'s inverse."""
    r = np.asarray(rotation, dtype=np.float64)
    angle = math.acos(min(1.0, max(-1.0, (float(np.trace(r)) - 1.0) / 2.0)))
    skew = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-6:
        return 0.5 * skew  # sin(angle) ~ angle
    if angle > math.pi - 1e-6:  # half a turn: the skew part vanishes; SciPy's way
        from scipy.spatial.transform import Rotation

        return Rotation.from_matrix(r).as_rotvec()
    return angle / (2.0 * math.sin(angle)) * skew


def as_quaternion(rotation: np.ndarray) -> list[float]:
    """A (3, 3) rotation matrix as pybullet's (x, y, z, w) quaternion (SciPy's ``from_matrix``).

    For placing pybullet bodies, which only worlds with a client have: SciPy is imported
    here, on first use, not by every environment.
    """
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rotation).as_quat().tolist()


def quaternion_to_matrix(quaternion: np.ndarray) -> np.ndarray:
    """An (x, y, z, w) quaternion as a (3, 3) rotation matrix (SciPy's ``from_quat``).

    SciPy normalises the quaternion and imports on first use, as :func:`as_quaternion`.
    """
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quaternion).as_matrix()
