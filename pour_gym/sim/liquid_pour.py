"""A liquid poured from a real container tilted at a fixed rate: onset, flow, how long it runs.

The fluid's validation (:mod:`pour_gym.fluid.validation`) uses shapes with closed-form
answers; this is the same fluid in a world with a catalogue container (the red cup), where
what is known is the order physics puts the liquids in: a more viscous one starts later,
flows slower and runs on longer (``docs/liquids.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation


@dataclass(frozen=True)
class LiquidPour:
    """One liquid poured from a container tilted at a fixed rate (:func:`liquid_pour`).

    Attributes:
        liquid: the liquid's name.
        particles: the fill, particles.
        onset_s: time from the tilt's start until 3 particles were past the rim plane, s.
        onset_deg: the tilt then, degrees (NaN: none poured).
        peak_flow: the largest outflow over any 0.2 s, particles/s.
        poured: particles past the rim plane by the end.
        stop_s: time from the start of the return upright until the last particle
            passed the rim plane, s (0: none after it started).
        times: (T,) s from the tilt's start.
        out: (T,) particles past the rim plane by then.
    """

    liquid: str
    particles: int
    onset_s: float
    onset_deg: float
    peak_flow: float
    poured: int
    stop_s: float
    times: np.ndarray
    out: np.ndarray


def liquid_pour(
    liquid: str = "water",
    container: str = "red_cup",
    fill: float = 0.6,
    rate: float = 30.0,
    tilt: float = 110.0,
    hold: float = 1.5,
    num_threads: int | None = None,
) -> LiquidPour:
    """Tilt a filled container about its lip at ``rate`` to ``tilt``, hold, set it upright.

    The container (no table under it) is filled to ``fill`` of its volume, settles for
    1 s, tilts at ``rate`` deg/s about its rim point on -x to ``tilt`` degrees, holds for
    ``hold`` s, returns upright at twice the rate and stands 2 s. A particle counts as
    poured once it is past the rim plane (the plane of the rim's centre, normal to the
    container's axis): a liquid that flows slower pours later and for longer.

    Args:
        liquid: a preset's name (:data:`pour_gym.fluid.liquid.PRESETS`).
        container: a container's name or mesh (the catalogue's red cup by default).
        fill: a fraction of the container's volume.
        rate: the tilt rate, deg/s.
        tilt: the largest tilt, degrees.
        hold: s at the largest tilt.
        num_threads: the fluid's threads.
    """
    from pour_gym.assets import resolve_asset
    from pour_gym.fluid.liquid import liquid_of
    from pour_gym.sim.world import World

    chosen = liquid_of(liquid)
    world = World("pbf", chosen.fluid_config(), table=False, num_threads=num_threads)
    try:
        asset = resolve_asset(container)
        geo = asset.geometry
        cup = world.add_container(asset, (0.0, 0.0, 0.3))
        world.fill(cup, volume=fill * geo.cavity_volume)
        count = len(world.particles)
        dt = 1 / 60
        for _ in range(60):
            world.step(dt)
        # The pivot: the rim point farthest along -x, which stays where it is.
        pivot_local = geo.rim_center + np.array([-geo.rim_radius, 0.0, 0.0])
        pivot = cup.to_world(pivot_local[None])[0]
        up_time, back_time = tilt / rate, tilt / (2.0 * rate)
        total = up_time + hold + back_time + 2.0
        poured = np.zeros(count, dtype=bool)
        removed = 0
        times, out = [], []
        angle = 0.0
        for k in range(int(np.ceil(total / dt))):
            t = (k + 1) * dt
            if t <= up_time:
                angle = rate * t
            elif t <= up_time + hold:
                angle = tilt
            else:
                angle = max(0.0, tilt - 2.0 * rate * (t - up_time - hold))
            # Tilted towards -x (the pivot's side): a rotation about +y by -angle.
            rot = Rotation.from_euler("y", -angle, degrees=True).as_matrix()
            world.set_pose(cup, pivot - rot @ pivot_local, rot)
            world.step(dt)
            local = (world.particles - cup.translation) @ cup.rotation
            poured |= local[:, 2] > geo.rim_center[2]
            # Poured particles fall with nothing under them: taken away 10 cm below the
            # pivot, before free fall makes them faster than any pour.
            gone = world.particles[:, 2] < pivot[2] - 0.1
            if gone.any():
                removed += int(np.count_nonzero(gone & poured))
                world.remove_particles(gone)
                poured = poured[~gone]
            times.append(t)
            out.append(removed + int(poured.sum()))
        times_a, out_a = np.array(times), np.array(out)
        started = np.flatnonzero(out_a >= 3)
        onset_s = float(times_a[started[0]]) if len(started) else float("nan")
        onset_deg = min(rate * onset_s, tilt) if len(started) else float("nan")
        window = max(1, round(0.2 / dt))
        flow = (out_a[window:] - out_a[:-window]) / (window * dt) if len(out_a) > window else [0]
        back = up_time + hold
        grew = np.flatnonzero(np.diff(out_a, prepend=0) > 0)
        last = float(times_a[grew[-1]]) if len(grew) else 0.0
        return LiquidPour(
            liquid=chosen.name,
            particles=count,
            onset_s=onset_s,
            onset_deg=float(onset_deg),
            peak_flow=float(np.max(flow)),
            poured=int(out_a[-1]),
            stop_s=max(0.0, last - back),
            times=times_a,
            out=out_a,
        )
    finally:
        world.close()
