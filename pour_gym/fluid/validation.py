"""The fluid against what a physicist would check: hydrostatics and the pour onset.

Two experiments in a straight cylinder cup (inner radius 36 mm, 4 mm walls, 6 mm base),
at any fluid parameters:

- :func:`settled_column`: particles for a column of height H settle for 2.5 s; twice
  their mean height must be ``N v / (pi R^2)`` (within 5 %), and in the bulk (a kernel
  radius from the walls and the free surface) the SPH density must be the rest density
  (mean absolute error under 3 %, over the last 0.5 s).
- :func:`pour_onset`: a cup filled to h and tilted slowly pours at ``tan(theta) =
  (H - h) / R`` (within 3 degrees).

``pour-gym bench accuracy`` prints both; ``tests/test_fluid.py`` asserts them. It also
prints :func:`shear_wave`: a transverse shear wave in a long tray, which a liquid damps
(at ``nu k^2``) and an elastic solid carries (at its shear wave speed); fitted by
:func:`fit_viscoelastic`, it gives the fluid's viscosity in m^2/s (the liquids'
calibration and check, :mod:`pour_gym.fluid.liquid`). Flows with known answers (efflux,
a dam break) are :mod:`pour_gym.fluid.flows`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pour_gym.fluid.pbf import PBFConfig, PBFluid
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf
from pour_gym.objects import cylinder_cup

R_IN, WALL, BASE = 0.036, 0.004, 0.006  # m: the cylinder's inner radius, wall and base
ONSET_HEIGHT = 0.1  # m: the cup the onset is measured in
# The shear-wave tray (m): inner width along x (half the wave's length), length along y,
# walls, base, and the fluid's depth in it.
TRAY_WIDTH, TRAY_LENGTH, TRAY_WALL, TRAY_BASE, TRAY_DEPTH = 0.12, 0.48, 0.005, 0.006, 0.02
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


@dataclass(frozen=True)
class ShearWave:
    """A transverse shear wave's amplitude over time, and the medium fitted to it.

    Attributes:
        wavelength: twice the tray's width, m (the wave number k is 2 pi over it).
        amplitude: the initial speed of the wave, m/s.
        times: (T,) s after the start.
        amplitudes: (T,) the velocity field's share along the wave, relative to its start.
        viscosity: the kinematic viscosity nu of the fitted medium, m^2/s.
        wave_speed: the fitted medium's elastic shear wave speed c, m/s (a liquid: 0).
    """

    wavelength: float
    amplitude: float
    times: np.ndarray
    amplitudes: np.ndarray
    viscosity: float
    wave_speed: float


def viscoelastic_mode(times: np.ndarray, k: float, nu: float, c: float) -> np.ndarray:
    """A shear mode's velocity over time in a Kelvin-Voigt medium, relative to its start.

    The mode's displacement u obeys ``u'' = -c^2 k^2 u - nu k^2 u'`` from rest (``u = 0``)
    at speed 1: a liquid (c = 0) decays as ``exp(-nu k^2 t)``, an elastic solid oscillates.

    Args:
        times: s.
        k: the wave number, 1/m.
        nu: kinematic viscosity, m^2/s.
        c: shear wave speed, m/s.
    """
    t = np.asarray(times, dtype=np.float64)
    b, w2 = nu * k * k, (c * k) ** 2
    disc = complex(b * b - 4.0 * w2) ** 0.5
    if abs(disc) < 1e-9 * max(b, 1e-12):  # critical damping: a double root
        r = -0.5 * b
        return (1.0 + r * t) * np.exp(r * t)
    r1, r2 = 0.5 * (-b + disc), 0.5 * (-b - disc)
    # v = C1 e^(r1 t) + C2 e^(r2 t), v(0) = 1, v'(0) = -b (no elastic force at rest).
    c1 = (-b - r2) / (r1 - r2)
    c2 = 1.0 - c1
    return np.real(c1 * np.exp(r1 * t) + c2 * np.exp(r2 * t))


def fit_viscoelastic(times: np.ndarray, amplitudes: np.ndarray, k: float) -> tuple[float, float]:
    """``(nu, c)`` of the Kelvin-Voigt mode (:func:`viscoelastic_mode`) fitted to a wave.

    Least squares over a grid of starts (a liquid's pure decay and solids of several
    stiffnesses), keeping the best.

    Args:
        times: s.
        amplitudes: the mode's velocity relative to its start (the first is 1).
        k: the wave number, 1/m.

    Raises:
        ValueError: fewer than 4 samples, or a start that is not 1.
    """
    from scipy.optimize import curve_fit

    t, a = np.asarray(times, dtype=np.float64), np.asarray(amplitudes, dtype=np.float64)
    if len(t) < 4 or abs(a[0] - 1.0) > 1e-9:
        raise ValueError("give at least 4 amplitudes over time, relative to the first (1)")
    # Where the amplitude first falls to 1/e: a liquid's decay time 1 / (nu k^2).
    below = np.flatnonzero(a < np.exp(-1.0))
    tau = t[below[0]] if len(below) else 2.0 * t[-1]
    best, best_cost = (1.0 / (tau * k * k), 0.0), np.inf
    for nu0 in (0.5 / (tau * k * k), 1.0 / (tau * k * k), 2.0 / (tau * k * k)):
        for c0 in (0.0, 0.03, 0.1, 0.3):
            try:
                (nu, c), _ = curve_fit(
                    lambda tt, nu, c: viscoelastic_mode(tt, k, nu, c), t, a, p0=(nu0, c0),
                    bounds=([0.0, 0.0], [np.inf, np.inf]),
                )  # fmt: skip
            except RuntimeError:  # no convergence from this start
                continue
            cost = float(np.sum((viscoelastic_mode(t, k, nu, c) - a) ** 2))
            if cost < best_cost:
                best, best_cost = (float(nu), float(c)), cost
    return best


def tray_field(cache_dir=None) -> SignedDistanceField:
    """The shear-wave tray's signed-distance field (1 mm grid): an open box, 10 cm deep."""
    import trimesh

    w, length, wall, base, height = TRAY_WIDTH, TRAY_LENGTH, TRAY_WALL, TRAY_BASE, 0.1
    outer = trimesh.creation.box([w + 2 * wall, length + 2 * wall, height])
    outer.apply_translation([0.0, 0.0, height / 2])
    inner = trimesh.creation.box([w, length, height])
    inner.apply_translation([0.0, 0.0, height / 2 + base])
    tray = trimesh.boolean.difference([outer, inner], engine="manifold")
    return build_sdf(tray, spacing=0.001, cache_dir=cache_dir)


def shear_wave(
    amplitude: float = 0.01,
    duration: float = 3.0,
    config: PBFConfig | None = None,
    num_threads: int | None = None,
    field: SignedDistanceField | None = None,
) -> ShearWave:
    """A shear wave across the tray: ``v_y = A cos(pi x / W)``, watched for ``duration`` s.

    The fluid (:data:`TRAY_DEPTH` deep) settles for 1 s; then
    every particle gets ``v_y = amplitude cos(pi (x + W/2) / W)``, a shear mode that the
    tray's walls at ``x = +-W/2`` let slide (the fluid's walls do not hold it back). Each
    0.05 s the velocity field of the middle half of the tray's length (away from the ends,
    where the flow turns) is projected on the mode. A Newtonian liquid's amplitude decays
    as ``exp(-nu k^2 t)`` with ``k = pi / W``; an elastic body's oscillates.

    Args:
        amplitude: the wave's speed, m/s (small, so that the flow stays laminar).
        duration: how long it is watched, s.
        config: the fluid's parameters (no table: the fluid stands on the tray's base, a
            wall like the others; every wall free-slip, ``no_slip`` off).
        num_threads: the fluid's threads.
        field: :func:`tray_field`, computed if not given.
    """
    # The mode slides along the tray's walls: walls that held a viscous liquid would damp
    # it there, and the wave would no longer measure the bulk's viscosity alone.
    cfg = dataclasses.replace(config or PBFConfig(), no_slip=False)
    field = field if field is not None else tray_field()
    s, w = cfg.spacing, TRAY_WIDTH
    gx = np.arange(-w / 2 + s / 2, w / 2, s)
    gy = np.arange(-TRAY_LENGTH / 2 + s / 2, TRAY_LENGTH / 2, s)
    gz = np.arange(TRAY_BASE + s / 2, TRAY_BASE + TRAY_DEPTH, s)
    fluid = PBFluid(np.stack(np.meshgrid(gx, gy, gz, indexing="ij"), -1).reshape(-1, 3), cfg,
                    floor=None, num_threads=num_threads)  # fmt: skip
    fluid.add_collider(field)
    for _ in range(10):
        fluid.step(0.1)

    def mode(x: np.ndarray) -> np.ndarray:
        return np.cos(np.pi * (x + w / 2) / w)

    fluid.v[:] = 0.0
    fluid.v[:, 1] = amplitude * mode(fluid.x[:, 0])
    dt, times, amplitudes = 0.05, [], []
    for k in range(round(duration / dt) + 1):
        middle = np.abs(fluid.x[:, 1]) < TRAY_LENGTH / 4
        m = mode(fluid.x[middle, 0])
        amplitudes.append(float((fluid.v[middle, 1] * m).sum() / (m * m).sum()))
        times.append(k * dt)
        if k * dt < duration - 1e-9:
            fluid.step(dt)
    t, a = np.array(times), np.array(amplitudes) / amplitudes[0]
    nu, c = fit_viscoelastic(t, a, np.pi / w)
    return ShearWave(2 * w, amplitude, t, a, nu, c)


def cylinder_field(height: float, cache_dir=None, radius: float = R_IN) -> SignedDistanceField:
    """The signed-distance field of the validation cylinder of a given height (1 mm grid).

    Args:
        height: its outer height, m.
        cache_dir: where the field is cached (default: the user cache).
        radius: its inner radius, m.
    """
    return build_sdf(cylinder_cup(radius, height, WALL, BASE), spacing=0.001, cache_dir=cache_dir)


def column_lattice(spacing: float, height: float, radius: float = R_IN) -> np.ndarray:
    """A cubic lattice filling the cylinder (inner ``radius``) from its base to ``height``, m."""
    g = np.arange(-radius + spacing / 2, radius, spacing)
    zs = np.arange(BASE + spacing / 2, BASE + height, spacing)
    pts = np.stack(np.meshgrid(g, g, zs, indexing="ij"), -1).reshape(-1, 3)
    return pts[np.hypot(pts[:, 0], pts[:, 1]) < radius - spacing / 2]


def lowest_points(pts: np.ndarray, count: int) -> np.ndarray:
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
    pts = lowest_points(column_lattice(cfg.spacing, COLUMN_HEIGHT - BASE - 0.01), count)
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
    fluid = PBFluid(lowest_points(column_lattice(cfg.spacing, depth), count), cfg,
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
