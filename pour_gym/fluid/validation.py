"""The fluid against what a physicist would check: hydrostatics and the pour onset.

Two experiments in a straight cylinder cup (inner radius 36 mm, 4 mm walls, 6 mm base),
at any fluid parameters:

- :func:`settled_column`: particles for a column of height H settle for 2.5 s; twice
  their mean height must be ``N v / (pi R^2)`` (within 5 %), and in the bulk (a kernel
  radius from the walls and the free surface) the SPH density must be the rest density
  (mean absolute error under 3 %, over the last 0.5 s).
- :func:`pour_onset`: a cup filled to h and tilted slowly pours at ``tan(theta) =
  (H - h) / R`` (within 3 degrees).

``pour-gym bench accuracy`` prints both; ``tests/test_fluid.py`` asserts them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pour_gym.fluid.pbf import PBFConfig, PBFluid
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf
from pour_gym.objects import cylinder_cup

R_IN, WALL, BASE = 0.036, 0.004, 0.006  # m: the cylinder's inner radius, wall and base
ONSET_HEIGHT = 0.1  # m: the cup the onset is measured in
COLUMN_HEIGHT = 0.13  # m: a cup deep enough for a column of 8.6 cm with room to spare


@dataclass(frozen=True)
class Column:
    """A settled column.

    Attributes:
        height: the column asked for, ``N v / (pi R^2)``, m.
        measured: twice the particles' mean height above the base, m.
        height_error: ``measured / height - 1``.
        density_error: mean absolute error of the bulk's density over rest density, over
            the last 0.5 s (NaN where the column has no bulk: under 200 particles).
        rms_speed: root mean square speed over the last 0.5 s, m/s.
        lost: particles that left the cup.
    """

    height: float
    measured: float
    height_error: float
    density_error: float
    rms_speed: float
    lost: int


@dataclass(frozen=True)
class Onset:
    """A pour onset.

    Attributes:
        fill: the fill, a fraction of the cup's depth.
        expected_deg: ``atan((H - h) / R)``, degrees.
        measured_deg: the tilt at which 3 particles stood over the rim plane, degrees
            (NaN if none did within 10 degrees past the expected onset).
        error_deg: measured less expected.
    """

    fill: float
    expected_deg: float
    measured_deg: float
    error_deg: float


def cylinder_field(height: float, cache_dir=None) -> SignedDistanceField:
    """The signed-distance field of the validation cylinder of a given height (1 mm grid)."""
    return build_sdf(cylinder_cup(R_IN, height, WALL, BASE), spacing=0.001, cache_dir=cache_dir)


def column_lattice(spacing: float, height: float) -> np.ndarray:
    """A cubic lattice filling the cylinder from its base to ``height`` above it, m."""
    g = np.arange(-R_IN + spacing / 2, R_IN, spacing)
    zs = np.arange(BASE + spacing / 2, BASE + height, spacing)
    pts = np.stack(np.meshgrid(g, g, zs, indexing="ij"), -1).reshape(-1, 3)
    return pts[np.hypot(pts[:, 0], pts[:, 1]) < R_IN - spacing / 2]


def _lowest(pts: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` lowest lattice points (layer by layer, in a fixed order)."""
    return pts[np.lexsort((pts[:, 1], pts[:, 0], pts[:, 2]))][:count]


def settled_column(
    height: float,
    config: PBFConfig | None = None,
    num_threads: int | None = None,
    field: SignedDistanceField | None = None,
) -> Column:
    """Settle a column of ``height`` m for 2.5 s in the tall cylinder; measure it.

    Args:
        height: the column's height, ``N v / (pi R^2)``, m.
        config: the fluid's parameters (default: the defaults).
        num_threads: the fluid's threads.
        field: the tall cylinder's field (:func:`cylinder_field` of
            :data:`COLUMN_HEIGHT`), computed if not given.
    """
    cfg = config or PBFConfig()
    field = field if field is not None else cylinder_field(COLUMN_HEIGHT)
    count = round(np.pi * R_IN**2 * height / cfg.particle_volume)
    pts = _lowest(column_lattice(cfg.spacing, COLUMN_HEIGHT - BASE - 0.01), count)
    fluid = PBFluid(pts, cfg, num_threads=num_threads)
    fluid.add_collider(field)
    energies, errors, bulk_sizes = [], [], []
    for k in range(25):  # 2.5 s
        fluid.step(0.1)
        energies.append(0.5 * np.mean(np.sum(fluid.v**2, axis=1)))
        if k >= 20:
            # The bulk: a kernel radius from the side wall, the base and the free surface.
            x = fluid.x
            bulk = (
                (np.hypot(x[:, 0], x[:, 1]) < R_IN - fluid.h - cfg.radius)
                & (x[:, 2] > BASE + fluid.h + cfg.radius)
                & (x[:, 2] < x[:, 2].max() - fluid.h)
            )
            bulk_sizes.append(int(bulk.sum()))
            errors.append(float(np.abs(fluid.relative_density()[bulk] - 1.0).mean()))
    x = fluid.x
    measured = 2.0 * float(x[:, 2].mean() - BASE)
    lost = int(np.count_nonzero(x[:, 2] > COLUMN_HEIGHT))
    return Column(
        height=height,
        measured=measured,
        height_error=measured / height - 1.0,
        density_error=float(np.mean(errors)) if min(bulk_sizes) > 200 else float("nan"),
        rms_speed=float(np.sqrt(2.0 * np.mean(energies[-5:]))),
        lost=lost,
    )


def pour_onset(
    fill: float,
    config: PBFConfig | None = None,
    num_threads: int | None = None,
    field: SignedDistanceField | None = None,
) -> Onset:
    """Fill the 10 cm cylinder to ``fill`` of its depth, tilt it slowly; the onset angle.

    The cup settles for 1 s, tilts quickly to 12 degrees before the expected onset, then
    at 5 degrees per second; the onset is the tilt at which 3 particles' surfaces reach
    over the rim plane.

    Args:
        fill: fraction of the cup's depth.
        config: the fluid's parameters.
        num_threads: the fluid's threads.
        field: the cylinder's field (:func:`cylinder_field` of :data:`ONSET_HEIGHT`).
    """
    cfg = config or PBFConfig()
    field = field if field is not None else cylinder_field(ONSET_HEIGHT)
    depth = ONSET_HEIGHT - BASE
    h = fill * depth
    count = round(np.pi * R_IN**2 * h / cfg.particle_volume)
    fluid = PBFluid(_lowest(column_lattice(cfg.spacing, depth), count), cfg,
                    num_threads=num_threads)  # fmt: skip
    cup = fluid.add_collider(field)
    for _ in range(60):
        fluid.step(1 / 60)
    expected = float(np.degrees(np.arctan((depth - h) / R_IN)))
    angle, onset = 0.0, float("nan")
    while angle < expected + 10.0:
        if angle < expected - 12.0:
            angle = min(expected - 12.0, angle + 20.0 / 60)
        if angle >= expected - 12.0:
            angle += 5.0 / 60
        cup.rotation = Rotation.from_euler("y", angle, degrees=True).as_matrix()
        fluid.step(1 / 60)
        if np.count_nonzero((fluid.x @ cup.rotation)[:, 2] > ONSET_HEIGHT - cfg.radius) >= 3:
            onset = angle
            break
    return Onset(fill, expected, onset, onset - expected)
