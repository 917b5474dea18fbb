"""The fluid against flows with known answers: efflux and a dam break (water).

- :func:`efflux`: a cylinder draining through a hole in its base, against Torricelli's
  law with a fitted discharge coefficient (:class:`Efflux`).
- :func:`dam_break`: a column released in a tank, its surge front against Martin and
  Moyce's measurements and Koshizuka and Oka's (:class:`DamBreak`).

``pour-gym bench liquids`` prints both; ``tests/test_liquid.py`` asserts them. The
statics, the pour onset and the shear wave are :mod:`pour_gym.fluid.validation`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pour_gym.errors import InputError
from pour_gym.fluid.pbf import PBFConfig, PBFluid
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf
from pour_gym.fluid.validation import (
    BASE,
    R_IN,
    WALL,
    column_lattice,
    cylinder_field,
    lowest_points,
)
from pour_gym.objects import cylinder_cup

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
    fluid = PBFluid(lowest_points(column_lattice(cfg.spacing, height - BASE, radius), count), cfg,
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
