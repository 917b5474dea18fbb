"""The pouring env's vector observations: the warped features, or raw state.

Pure functions of the step's quantities (the lip, the tilt, the containers' geometry as
the policy knows it, the particles and their counts), so the numbers a policy reads are
defined in one place, apart from the env that gathers them.
"""

from __future__ import annotations

import numpy as np

from pour_gym.errors import InputError
from pour_gym.features import ContainerGeometry, fluid_features, relative_distance_height
from pour_gym.sim import Container

FEATURE_NAMES = (
    "lip_dx",  # (target rim centre - lip) along x, over the target's rim radius
    "lip_dy",  # the same along y
    "lip_height",  # lip above the target's rim centre, over the target's height
    "tilt",  # tilt of the source over 90 degrees
    "f3_source",  # fluid in the source over the source's volume (thesis f3)
    "f4_source",  # fluid in the source above its lip over its volume (thesis f4)
    "poured",  # particles in the target over the target amount
    "in_flight",  # moving particles in no container over the target amount
    "spilled",  # resting particles in no container over the target amount
    "target_fill",  # target amount over the target's volume
    "stream_f1",  # mean thesis f1 of the particles in flight for the target (0 if none)
    "target_rim_radius",  # in 10 cm
    "target_height",  # in 10 cm
    "source_rim_radius",  # in 10 cm
    "source_height",  # in 10 cm
    "in_source",  # particles in the source over the target amount
)
STATE_NAMES = (
    "lip_x",
    "lip_y",
    "lip_z",
    "tilt_rad",
    "target_x",
    "target_y",
    "target_yaw_sin",
    "target_yaw_cos",
    "source_size_x",
    "source_size_y",
    "source_size_z",
    "target_size_x",
    "target_size_y",
    "target_size_z",
    "in_source",  # particle counts over the initial fill
    "poured",
    "in_flight",
    "spilled",
    "target_amount",
)
# With observe_flow: the particles that left the source over the last step, over the target
# amount (the flow the scripted expert regulates: a difference of two steps' counts).
FLOW_NAME = "out_flow"
# Every observation entry is clipped to +-this.
OBS_LIMIT = 10.0


def observation_names(
    vector: str | None, observe_flow: bool, held: tuple[str, ...]
) -> tuple[str, ...]:
    """The entries of a vector observation, by name (none without a vector mode).

    Args:
        vector: ``"features"``, ``"state"`` or None.
        observe_flow: ``FLOW_NAME`` follows the mode's entries.
        held: the holder's own entries, last.
    """
    if not vector:
        return ()
    names = FEATURE_NAMES if vector == "features" else STATE_NAMES
    return names + ((FLOW_NAME,) if observe_flow else ()) + held


def hidden_entries(
    hide: str | tuple[str, ...] | list[str], names: tuple[str, ...], obs_mode: object
) -> tuple[tuple[str, ...], np.ndarray]:
    """The entries ``hide`` names (that read 0), checked, and their indices in ``names``.

    Raises:
        InputError: naming the entries ``obs_mode`` does not have, and the ones it has.
    """
    hide = (hide,) if isinstance(hide, str) else tuple(hide)
    unknown = sorted(set(hide) - set(names))
    if unknown:
        raise InputError(
            f"hide names observation entries; {obs_mode!r} has no {unknown} (it has "
            f"{', '.join(names) or 'no vector entries'})"
        )
    # Indices, not names, on every step.
    return hide, np.array([names.index(h) for h in hide], dtype=np.int64)


def out_flow(prev: dict, counts: dict, target_amount: int) -> float:
    """The ``FLOW_NAME`` entry: particles out of the source over a step, over the amount.

    Args:
        prev: the counts before the step (``in_source``).
        counts: the counts after it.
        target_amount: particles.
    """
    return (prev["in_source"] - counts["in_source"]) / target_amount


def feature_vector(
    lip: np.ndarray,
    tilt: float,
    gs: ContainerGeometry,
    gt: ContainerGeometry,
    source: Container,
    target: Container,
    particles: np.ndarray,
    counts: dict,
    target_amount: int,
    particle_volume: float,
) -> list[float]:
    """The ``FEATURE_NAMES`` entries (unclipped).

    Args:
        lip: the source's lip, m (world).
        tilt: the source's tilt, deg.
        gs: the source's geometry as the policy knows it (perceived, or true).
        gt: the target's geometry likewise.
        source: the posed source container (the physics').
        target: the posed target container.
        particles: (N, 3) positions, m.
        counts: the step's census (``where`` per particle: the container's index, or
            negative in flight; ``poured``, ``in_flight``, ``spilled``, ``in_source``).
        target_amount: particles.
        particle_volume: m^3 a particle stands for.
    """
    c, t, v = counts, target_amount, particle_volume
    centre = target.to_world(gt.rim_center)
    f3, f4 = fluid_features(
        gs, particles, source.rotation, source.translation, v, inside=c["where"] == source.index
    )
    flight = c["where"] < 0
    stream = 0.0
    if np.any(flight):
        f1, _ = relative_distance_height(gt, particles[flight], target.rotation, target.translation)
        stream = float(f1.mean())
    return [
        (centre[0] - lip[0]) / gt.rim_radius,
        (centre[1] - lip[1]) / gt.rim_radius,
        (lip[2] - centre[2]) / gt.height,
        tilt / 90.0,
        f3,
        f4,
        c["poured"] / t,
        c["in_flight"] / t,
        c["spilled"] / t,
        t * v / gt.cavity_volume,
        stream,
        gt.rim_radius / 0.1,
        gt.height / 0.1,
        gs.rim_radius / 0.1,
        gs.height / 0.1,
        c["in_source"] / t,
    ]


def state_vector(
    lip: np.ndarray,
    tilt: float,
    target_pos: np.ndarray,
    target_yaw: float,
    size_s: np.ndarray,
    size_t: np.ndarray,
    counts: dict,
    fill: int,
    target_amount: int,
) -> list[float]:
    """The ``STATE_NAMES`` entries (unclipped).

    Args:
        lip: the source's lip, m (world).
        tilt: the source's tilt, deg.
        target_pos: the target's place on the table, m.
        target_yaw: the target's turn about the vertical, rad.
        size_s: the source's bounding-box size, m.
        size_t: the target's likewise.
        counts: the step's census.
        fill: the source's initial fill, particles.
        target_amount: particles.
    """
    c, n0 = counts, fill
    return [
        *lip,
        np.radians(tilt),
        target_pos[0],
        target_pos[1],
        np.sin(target_yaw),
        np.cos(target_yaw),
        *(size_s / 0.1),
        *(size_t / 0.1),
        c["in_source"] / n0,
        c["poured"] / n0,
        c["in_flight"] / n0,
        c["spilled"] / n0,
        target_amount / n0,
    ]
