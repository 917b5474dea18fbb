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
calibration and check, :mod:`pour_gym.fluid.liquid`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pour_gym.errors import InputError
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


EFFLUX_HEIGHT = 0.12  # m: the holed cylinder's outer height
HOLE_RADIUS = 0.012  # m: the hole in its base (4.8 particle spacings across at 5 mm)
JET_START = 0.1  # s after the hole opens: the discharge coefficient is fitted from here


@dataclass(frozen=True)
class Efflux:
    """A cylinder draining through a hole in its base (:func:`efflux`).

    Torricelli's law with a discharge coefficient ``C_d``, ``Q = C_d a sqrt(2 g h / (1 -
    (a / A)^2))`` (a hole of area a in a cylinder of cross-section A), makes the level's
    square root fall linearly, at ``C_d (a / A) sqrt(g / 2) / sqrt(1 - (a / A)^2)``: the
    level reaches ``h1`` when it has fallen ``sqrt(h0) - sqrt(h1)`` at that rate.

    Attributes:
        discharge: ``C_d`` fitted to the level's fall from :data:`JET_START` after the hole
            opens to h0 / 2, by least squares on sqrt(h) over time.
        drain_s: the time the level took to fall from h0 to ``end_height``, s.
        torricelli_s: the time Torricelli's law gives for it with ``discharge``, s.
        start_height: h0, m.
        end_height: h1, m.
        times: (T,) s.
        heights: (T,) the level, m (the fluid left in the cup over its cross-section).
    """

    discharge: float
    drain_s: float
    torricelli_s: float
    start_height: float
    end_height: float
    times: np.ndarray
    heights: np.ndarray


def holed_cylinder_field(
    hole_radius: float = HOLE_RADIUS,
    cache_dir=None,
    radius: float = R_IN,
    height: float = EFFLUX_HEIGHT,
) -> SignedDistanceField:
    """The efflux cylinder's field (1 mm grid): a hole of ``hole_radius`` m in its base.

    The validation cylinder's walls, ``radius`` m inside and ``height`` m tall (by default
    the validation cylinder's, 12 cm), the hole through the middle of the base.
    """
    import trimesh

    cup = cylinder_cup(radius, height, WALL, BASE)
    hole = trimesh.creation.cylinder(radius=hole_radius, height=4 * BASE, sections=64)
    holed = trimesh.boolean.difference([cup, hole], engine="manifold")
    return build_sdf(holed, spacing=0.001, cache_dir=cache_dir)


def efflux(
    start_height: float = 0.08,
    end_height: float = 0.01,
    config: PBFConfig | None = None,
    num_threads: int | None = None,
    hole_radius: float = HOLE_RADIUS,
    scale: float = 1.0,
) -> Efflux:
    """Fill the holed cylinder to ``start_height``, open the hole, watch the level fall.

    The fluid settles for 1 s in the cylinder without the hole (the same walls), then
    the holed one takes its place; every 1/60 s the level is the fluid still above the
    base over the cup's cross-section, and particles 5 cm below the cup are removed.

    Args:
        start_height: the column, m above the base.
        end_height: the level at which the draining time stops, m.
        config: the fluid's parameters.
        num_threads: the fluid's threads.
        hole_radius: m.
        scale: the cylinder's radius and height, the hole's radius and both heights are
            ``scale`` times those given: at twice the spacing, scale 2 puts as many
            particles across every length as scale 1 does (a geometrically similar
            efflux, whose discharge coefficient says what the resolution does).

    Raises:
        InputError: a scale that is not above 0.
        ValueError: a level that never reaches ``end_height`` within 10 s.
    """
    if not (np.isfinite(scale) and scale > 0.0):
        raise InputError(f"scale must be a factor above 0 (2: twice the vessel), not {scale}")
    cfg = config or PBFConfig()
    radius, hole_radius = scale * R_IN, scale * hole_radius
    start_height, end_height = scale * start_height, scale * end_height
    height = scale * EFFLUX_HEIGHT
    count = round(np.pi * radius**2 * start_height / cfg.particle_volume)
    fluid = PBFluid(_lowest(column_lattice(cfg.spacing, height - BASE, radius), count), cfg,
                    floor=None, num_threads=num_threads)  # fmt: skip
    plug = fluid.add_collider(cylinder_field(height, radius=radius))
    for _ in range(60):
        fluid.step(1 / 60)
    fluid.colliders.remove(plug)
    fluid.add_collider(holed_cylinder_field(hole_radius, radius=radius, height=height))
    area = np.pi * radius**2
    dt, times, heights = 1 / 60, [0.0], []

    def level() -> float:
        inside = fluid.x[:, 2] > BASE
        return float(np.count_nonzero(inside)) * cfg.particle_volume / area

    h0 = level()
    heights.append(h0)
    while heights[-1] > end_height:
        if times[-1] > 10.0:
            raise ValueError(f"the level stayed at {heights[-1]:.3f} m after 10 s")
        fluid.step(dt)
        gone = fluid.x[:, 2] < -0.05
        if gone.any():
            fluid.remove(gone)
        times.append(times[-1] + dt)
        heights.append(level())
    t, h = np.array(times), np.array(heights)
    # Torricelli's law is quasi-steady: the fit starts once the jet has formed (the
    # column's first accelerating frames burst out at some spacings: 3.5 mm's C_d was
    # 0.59 with them, 0.54 without, between 4 mm's 0.51 and 3 mm's 0.54).
    first = (t >= JET_START) & (h >= 0.5 * h0)
    slope = np.polyfit(t[first], np.sqrt(h[first]), 1)[0]
    ratio = (hole_radius / radius) ** 2  # a / A
    # The level's square root falls at C_d (a / A) sqrt(g / 2) / sqrt(1 - (a / A)^2) (the
    # last factor: the fluid's speed of approach, 0.6 % at the default hole).
    rate = ratio * np.sqrt(9.81 / 2.0) / np.sqrt(1.0 - ratio * ratio)
    discharge = float(-slope / rate)
    torricelli = (np.sqrt(h0) - np.sqrt(end_height)) / (discharge * rate)
    return Efflux(discharge, float(t[-1]), float(torricelli), h0, end_height, t, h)


# Martin and Moyce (1952), Phil. Trans. R. Soc. A 244, 312-324, Fig. 3: the surge front
# of a collapsing column of width a and height 2a (n^2 = 2), as Z = x / a against
# T = t sqrt(2 g / a), for a = 2.25 in and a = 1.125 in (digitised by the PySPH project,
# pysph/examples/db_exp_data.py). The two columns' fronts differ by up to 15 % at one T:
# the experiment's own scatter.
MARTIN_MOYCE = {
    "a = 2.25 in": (
        (0.832, 1.219, 1.997, 2.547, 3.345, 4.034, 4.418, 5.091, 5.685, 6.306, 6.822, 7.439),
        (1.217, 1.474, 2.292, 2.995, 4.134, 4.944, 5.881, 6.980, 7.945, 8.966, 9.986, 10.963),
    ),
    "a = 1.125 in": (
        (0.849, 1.212, 1.602, 2.283, 2.950, 3.598, 3.905, 4.592, 4.961, 5.316),
        (1.245, 1.443, 1.884, 2.689, 3.728, 4.528, 4.999, 5.841, 6.271, 6.717),
    ),
}
# Koshizuka and Oka (1996), Nucl. Sci. Eng. 123, 421-434: the surge front of their own
# experiment, a column L = 14.6 cm wide and 2L high (n^2 = 2, as Martin and Moyce's), as
# x / L against t sqrt(2 g / L) (digitised by the PySPH project, as above); a second
# laboratory's release of the same column, to tell the method from one experiment's.
KOSHIZUKA_OKA = (
    (0.0, 0.381, 0.769, 1.153, 1.537, 1.935, 2.323, 2.719, 3.096),
    (1.000, 1.111, 1.252, 1.505, 1.892, 2.241, 2.615, 3.003, 3.624),
)
DAM_WIDTH = 0.05715  # m: a = 2.25 in, Martin and Moyce's larger column
TANK_LENGTH, TANK_DEPTH, TANK_WALL = 0.40, 0.04, 0.005  # m: x reach, y width, walls


@dataclass(frozen=True)
class DamBreak:
    """A collapsing column's surge front (:func:`dam_break`), in Martin and Moyce's terms.

    Attributes:
        width: the column's width a, m (its height 2a).
        gate_speed: the dam's upward speed on release, m/s (0: removed at once).
        floor_friction: the floor's friction, 1/s (None: it lets the liquid slide).
        substep: the fluid's largest substep, s (``PBFConfig.substep``; the envs' 1/240).
        times: (T,) ``t sqrt(2 g / a)``.
        fronts: (T,) ``x / a``, the front's distance from the back wall over a.
        band: (T, 2) the lowest and highest front Martin and Moyce measured at each time
            (their two columns, interpolated; NaN past their last point).
        inside: the share of the times within the band widened by 5 % either way.
        settled_speed: the column's rms particle speed when the dam goes, m/s: a column
            that has not come to rest behind it (a solver that does not hold it) is not
            the experiment's start.
        settled_compression: the 90th percentile of the particles' density over rest when
            the dam goes (the fluid's own particles, walls not counted, so it reads the
            bulk and the base): above 1, the base of the column is squeezed, as water's
            is not.
    """

    width: float
    gate_speed: float
    floor_friction: float | None
    substep: float
    times: np.ndarray
    fronts: np.ndarray
    band: np.ndarray
    inside: float
    settled_speed: float
    settled_compression: float


def tank_fields(width: float = DAM_WIDTH, cache_dir=None):
    """The dam break's tank (an open box) and its dam (a slab at x = a), as fields."""
    import trimesh

    inner = np.array([TANK_LENGTH, TANK_DEPTH, 3.0 * width])
    outer = trimesh.creation.box(inner + 2.0 * TANK_WALL)
    outer.apply_translation([TANK_LENGTH / 2, 0.0, inner[2] / 2])
    hollow = trimesh.creation.box(inner + np.array([0.0, 0.0, 2.0 * TANK_WALL]))
    hollow.apply_translation([TANK_LENGTH / 2, 0.0, inner[2] / 2 + TANK_WALL])
    tank = trimesh.boolean.difference([outer, hollow], engine="manifold")
    dam = trimesh.creation.box([0.01, TANK_DEPTH + 0.02, 3.0 * width])
    dam.apply_translation([width + 0.005, 0.0, 1.5 * width])
    return (build_sdf(tank, spacing=0.001, cache_dir=cache_dir),
            build_sdf(dam, spacing=0.001, cache_dir=cache_dir))  # fmt: skip


def gate_speed_limit(height: float) -> float:
    """The slowest gate that still releases a column as a dam break, m/s.

    Lauber and Hager (1998, J. Hydraul. Res. 36(5), 761-773) take a gate lifted within
    ``sqrt(2 h / g)`` as an instantaneous release of a column ``h`` deep: lifted at
    constant speed, it clears the column at ``sqrt(g h / 2)``.

    Args:
        height: the column's height, m.
    """
    return float(np.sqrt(9.81 * height / 2.0))


def dam_break(
    width: float = DAM_WIDTH,
    config: PBFConfig | None = None,
    num_threads: int | None = None,
    fields=None,
    gate_speed: float = 0.0,
    floor_friction: float | None = None,
    hold: float = 1.0,
    settle_damping: float = 0.0,
) -> DamBreak:
    """A column a wide and 2a high, held by a dam (1 s), released; its front over time.

    The tank's walls (free-slip, as all walls here) run along x from the back wall at
    x = 0 to the far one at :data:`TANK_LENGTH`; the column spans the tank's 4 cm of y, so
    the flow is the experiment's plane one. The front is the third particle farthest
    along x (a lone drop ahead is not the surge), sampled every 1/120 s until it is two
    spacings from the far wall.

    Args:
        width: a, m.
        config: the fluid's parameters.
        num_threads: the fluid's threads.
        fields: :func:`tank_fields`, computed if not given.
        gate_speed: 0 removes the dam at once; above 0, it is lifted at this speed (m/s),
            as a gate is in a flume (:func:`gate_speed_limit`), and removed once clear of
            the column.
        floor_friction: None: the tank's floor lets the liquid slide, as its walls do. A
            rate (1/s): the tank stands on the envs' table, whose friction takes the
            horizontal velocity of the particles touching it down at this rate
            (``PBFConfig.floor_friction``; the envs' is 20), as a real floor holds back
            the thin sheet at the front.
        hold: how long the dam holds the column before the release, s.
        settle_damping: the share of the particles' velocity taken away after each 1/60 s
            step of the hold (0: none; 0.5 halves it), a damped settling as SPH codes
            relax a column before its release.
    """
    if not (np.isfinite(gate_speed) and gate_speed >= 0.0):
        raise InputError(f"gate_speed must be a speed of 0 m/s or more, not {gate_speed}")
    if not (np.isfinite(hold) and hold >= 0.0):
        raise InputError(f"hold must be a time of 0 s or more, not {hold}")
    if not (np.isfinite(settle_damping) and 0.0 <= settle_damping < 1.0):
        raise InputError(
            f"settle_damping is the share of the velocity taken away each step, from 0 to "
            f"below 1, not {settle_damping}"
        )
    if floor_friction is not None and not (np.isfinite(floor_friction) and floor_friction >= 0):
        raise InputError(f"floor_friction must be a rate of 0 1/s or more, not {floor_friction}")
    cfg = config or PBFConfig()
    if floor_friction is not None:
        if cfg.viscosity > 0.0:
            # Its wall drag would count the tank's floor and the table both.
            raise InputError(
                "a dam break on the table (floor_friction) is for water only: give a liquid "
                "without a viscosity, or floor_friction=None"
            )
        cfg = dataclasses.replace(cfg, floor_friction=float(floor_friction))
    tank, dam = fields if fields is not None else tank_fields(width)
    s = cfg.spacing
    gx = np.arange(s / 2, width, s)
    gy = np.arange(-TANK_DEPTH / 2 + s / 2, TANK_DEPTH / 2, s)
    gz = np.arange(s / 2, 2.0 * width, s)  # the tank's floor is z = 0
    pts = np.stack(np.meshgrid(gx, gy, gz, indexing="ij"), -1).reshape(-1, 3)
    # The table at the tank's floor (z = 0): a particle's density counts the nearer of the
    # two as its wall, so for water the table adds only its friction.
    floor = None if floor_friction is None else 0.0
    fluid = PBFluid(pts, cfg, floor=floor, num_threads=num_threads)
    fluid.add_collider(tank)
    plug = fluid.add_collider(dam)
    for _ in range(round(60 * hold)):
        fluid.step(1 / 60)
        fluid.v *= 1.0 - settle_damping
    settled = float(np.sqrt(np.mean(np.sum(fluid.v**2, axis=1))))
    compression = float(np.percentile(fluid.relative_density(), 90))
    scale = np.sqrt(2.0 * 9.81 / width)
    dt, t, times, fronts = 1 / 120, 0.0, [], []
    while True:
        front = float(np.sort(fluid.x[:, 0])[-3])
        times.append(t * scale)
        fronts.append(front / width)
        if front > TANK_LENGTH - 2 * s or t > 2.0:
            break
        # The gate's bottom edge rises from the floor; the fluid moves it over the step.
        lift = gate_speed * (t + dt)
        if plug in fluid.colliders:
            if gate_speed == 0.0 or lift > 2.0 * width:
                fluid.colliders.remove(plug)
            else:
                plug.translation = np.array([0.0, 0.0, lift])
        fluid.step(dt)
        t += dt
    times_a, fronts_a = np.array(times), np.array(fronts)
    curves = np.stack([np.interp(times_a, np.array(T), np.array(Z), left=np.nan, right=np.nan)
                       for T, Z in MARTIN_MOYCE.values()])  # fmt: skip
    # The band: the lowest and highest series measured at each time (where only one
    # reaches, its value); NaN before and after both.
    seen = ~np.isnan(curves).all(axis=0)
    band = np.full((len(times_a), 2), np.nan)
    band[seen, 0] = np.nanmin(curves[:, seen], axis=0)
    band[seen, 1] = np.nanmax(curves[:, seen], axis=0)
    within = (fronts_a >= 0.95 * band[:, 0]) & (fronts_a <= 1.05 * band[:, 1])
    inside = float(within[seen].mean()) if seen.any() else float("nan")
    return DamBreak(
        width,
        float(gate_speed),
        floor_friction,
        cfg.substep,
        times_a,
        fronts_a,
        band,
        inside,
        settled,
        compression,
    )
