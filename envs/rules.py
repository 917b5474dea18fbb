"""The pouring task's rules, in one place.

The episode's fill and amount, the counts (what has spilled), the tolerance, when an
episode ends, success, why it ended, the amount's reward terms and the shaping
potentials: pure functions of the counts a step takes (particles in the source, in the
target, in flight and spilled), the tilt, the lip and the holder's failure.
:class:`~pour_gym.envs.pour.PourEnv` steps by them and :class:`~pour_gym.envs.task.Task`
scores episodes by them. How the actions are encoded is :mod:`pour_gym.envs.actions`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.errors import InputError

if TYPE_CHECKING:
    from pour_gym.sim.census import Census

# A particle in no container moving slower than this (m/s) has come to rest: spilled.
RESTING_SPEED = 0.05
# The fill left over when the source's fill is sized to the task, particles.
FILL_MARGIN = 100
# The target amount's range at 5 mm, particles of 0.125 ml (scaled to the same volumes at
# another spacing).
AMOUNT_RANGE = (100, 300)

# The pouring env's reward terms, in their order (each has a ``<term>_weight`` argument).
REWARD_TERMS = (
    "progress", "overshoot", "spill", "success", "time", "aim", "upright", "tilt", "control",
)  # fmt: skip
# Where the aim shaping draws the lip: this many target rim radii before its centre.
AIM_OFFSET = 0.5
# The source counts as upright below this tilt (deg).
UPRIGHT_DEG = 3.0

# How a pouring episode ended, first match wins (outcome); README: "why episodes fail".
POUR_OUTCOMES = {
    "success": "the amount within tolerance, nothing spilled, the source upright",
    "spilled": "a particle came to rest outside both containers",
    "overshot": "more than the target amount plus the tolerance in the target",
    "never_poured": "no pour happened (the source never tilted far enough over the target)",
    "under_poured": "poured, but stopped short of the target amount less the tolerance",
    "unfinished": "the amount right and nothing spilled, but the episode was cut short "
    "before the source stood upright with nothing in flight",
}


def tolerance(target_amount: int) -> int:
    """How far the poured amount may miss the target, particles: 10 %, at least 5."""
    return max(5, round(0.1 * target_amount))


def amount_option(options: dict, particle_volume: float) -> int | None:
    """The reset options' target amount in particles: ``target_amount``, or ``target_ml``.

    Args:
        options: the reset's options.
        particle_volume: m^3 a particle stands for.

    Raises:
        InputError: both given, or a ``target_ml`` that is not a positive number.
    """
    if "target_ml" not in options:
        return options.get("target_amount")
    if options.get("target_amount") is not None:
        raise InputError("give the amount as target_amount (particles) or target_ml, not both")
    ml = options["target_ml"]
    if not isinstance(ml, (int, float)) or not ml > 0:
        raise InputError(f"target_ml is a positive number of millilitres, not {ml!r}")
    return max(1, round(ml * 1e-6 / particle_volume))


def episode_amounts(
    capacity_source: int,
    capacity_target: int,
    amount_range: tuple[int, int],
    source_particles: int | None,
    rng: np.random.Generator,
    amount: int | None = None,
    margin: int | None = None,
    per_5mm: float = 1.0,
) -> tuple[int, int]:
    """An episode's fill of the source and its target amount, particles.

    Args:
        capacity_source: particles the source holds (60 % of its cavity).
        capacity_target: particles the target holds, likewise.
        amount_range: (low, high) of the target amount drawn, before the capacities.
        source_particles: a fixed fill, or None to size it to the task (the amount plus
            ``FILL_MARGIN``).
        rng: draws the amount when ``amount`` is None.
        amount: the reset option ``target_amount``.
        margin: the reset option ``fill_margin``: the fill is then the amount plus it.
        per_5mm: particles at the episode's spacing per 5 mm particle: ``FILL_MARGIN``
            and the 50 left in a fixed fill are counts of 5 mm particles.

    Returns:
        ``(fill, amount)``, the fill at most the source's capacity.

    Raises:
        InputError: a margin with a fixed fill or below 0, or an amount not in
            [1, fill].
    """
    fill_margin, spare = round(FILL_MARGIN * per_5mm), round(50 * per_5mm)
    if source_particles is None:
        most = capacity_source - fill_margin
    else:
        most = min(source_particles, capacity_source) - spare
    hi = max(1, min(amount_range[1], most, capacity_target))
    lo = min(amount_range[0], hi)
    amount = int(rng.integers(lo, hi + 1)) if amount is None else int(amount)
    fill = source_particles
    if margin is not None:
        if source_particles is not None or int(margin) < 0:
            raise InputError(
                "the reset option fill_margin must be a count of particles >= 0, and only "
                f"applies when source_particles is None (got {margin} with "
                f"source_particles={source_particles})"
            )
        fill = amount + int(margin)
    fill = min(fill if fill is not None else amount + fill_margin, capacity_source)
    if not 1 <= amount <= fill:
        raise InputError(f"target_amount must be in [1, {fill}] particles, not {amount}")
    return fill, amount


def check_amounts(
    source_particles: int | None,
    amount_range: tuple[int, int] | None,
    per_5mm: float,
    pour_threshold: int,
    pour_steps: int,
) -> tuple[int, int]:
    """The target amount's range, particles, with the fill and the pour rule checked.

    Args:
        source_particles: the fill asked for (None: sized to the task).
        amount_range: the target amount's range asked for (None: ``AMOUNT_RANGE`` scaled).
        per_5mm: particles at the fluid's spacing per particle at 5 mm.
        pour_threshold: particles out of the source that make a pour.
        pour_steps: steps in a row they must stay out.

    Raises:
        InputError: naming the argument out of its range.
    """
    if source_particles is not None and source_particles < 100:
        raise InputError(f"source_particles must be at least 100, not {source_particles}")
    lo, hi = amount_range or [round(n * per_5mm) for n in AMOUNT_RANGE]
    if not 1 <= lo <= hi:
        raise InputError(f"amount_range must be (low, high) with 1 <= low <= high: {lo, hi}")
    if pour_threshold < 1 or pour_steps < 1:
        raise InputError(
            f"pour_threshold and pour_steps must be at least 1, not {pour_threshold}, {pour_steps}"
        )
    return lo, hi


def pour_counts(census: Census, velocities: np.ndarray, source: int, target: int) -> dict:
    """Particles in the source, in the target, in flight and spilled (and where).

    Args:
        census: where every particle is (:meth:`pour_gym.sim.World.census`).
        velocities: (N, 3) the particles' velocities, m/s.
        source: the source's index among the world's containers.
        target: the target's, likewise.

    Returns:
        ``{"in_source", "poured", "in_flight", "spilled", "where"}``: a particle in no
        container is in flight while faster than ``RESTING_SPEED``, spilled once slower.
    """
    elsewhere = census.where < 0
    speed = np.linalg.norm(velocities, axis=1) if census.elsewhere else None
    moving = elsewhere & (speed > RESTING_SPEED) if speed is not None else elsewhere
    return {
        "in_source": int(census.counts[source]),
        "poured": int(census.counts[target]),
        "in_flight": int(np.count_nonzero(moving)),
        "spilled": int(np.count_nonzero(elsewhere & ~moving)),
        "where": census.where,
    }


def out_of_source(info: Mapping) -> int:
    """Particles that have left the source so far (in the target, in flight, spilled)."""
    return info["poured"] + info["in_flight"] + info["spilled"]


def running_rise(out: float, most: float) -> tuple[float, float]:
    """How far ``out`` rose above its running most ``most``, and the new most.

    What has left the source, counted as a running maximum: a particle flickering across
    the rim, in and out of the source's cavity, counts once (its +1/-1 as a flow would
    stall a regulator pouring by it). The env's flow form and the scripted expert
    regulate this rise.
    """
    new = max(out, most)
    return new - most, new


@dataclass
class PourTally:
    """What has left the source over an episode, step by step.

    Attributes:
        threshold: particles out of the source that make a pour (``pour_threshold``).
        steps: steps in a row they must stay out for a pour (``pour_steps``).
        most: the most particles out of the source so far.
        run: steps in a row with ``threshold`` or more out.
        poured_any: a pour has happened.
        flow: the rise of ``most`` over the last step, target amounts (the flow that the
            ``"flow"`` tilt form regulates).
    """

    threshold: int
    steps: int
    most: int
    run: int = 0
    poured_any: bool = False
    flow: float = 0.0

    def update(self, out: int, target_amount: int) -> None:
        """Count a step after which ``out`` particles are out of the source."""
        rise, self.most = running_rise(out, self.most)
        self.flow = rise / target_amount
        self.run = self.run + 1 if out >= self.threshold else 0
        self.poured_any = self.poured_any or self.run >= self.steps


def succeeded(poured: int, spilled: int, tilt: float, target_amount: int, tol: int) -> bool:
    """The amount within the tolerance, nothing spilled, the source upright."""
    return abs(poured - target_amount) <= tol and spilled == 0 and tilt < UPRIGHT_DEG


def episode_end(
    counts: Mapping[str, int],
    tilt: float,
    poured_any: bool,
    failure: object,
    target_amount: int,
    tol: int,
) -> tuple[bool, bool]:
    """Whether a step ends its episode, and whether in success.

    An episode ends when the holder failed, or with nothing in flight once the source
    poured and stands upright again, or is empty.

    Args:
        counts: the step's ``in_source``, ``poured``, ``in_flight`` and ``spilled``.
        tilt: the source's tilt, deg.
        poured_any: a pour happened in the episode (the env's pour threshold and steps).
        failure: the holder's failure (anything true: failed).
        target_amount: the target amount, particles.
        tol: :func:`tolerance` of it.

    Returns:
        (terminated, success).
    """
    settled = counts["in_flight"] == 0
    upright = tilt < UPRIGHT_DEG
    ended = settled and ((poured_any and upright) or counts["in_source"] == 0)
    terminated = bool(failure or ended)
    success = (
        terminated
        and not failure
        and succeeded(counts["poured"], counts["spilled"], tilt, target_amount, tol)
    )
    return terminated, success


def amount_terms(
    prev: Mapping[str, int], counts: Mapping[str, int], target_amount: int, success: bool
) -> dict[str, float]:
    """The reward's terms of the amount: ``progress``, ``overshoot``, ``spill``, ``success``.

    Changes over the step, in target amounts: poured up to the target, poured beyond it
    (negative), spilled (negative); ``success`` 1 on the step that ends in success.
    """
    t = target_amount
    return {
        "progress": (min(counts["poured"], t) - min(prev["poured"], t)) / t,
        "overshoot": -(max(counts["poured"] - t, 0) - max(prev["poured"] - t, 0)) / t,
        "spill": -(counts["spilled"] - prev["spilled"]) / t,
        "success": float(success),
    }


def shaping_potentials(
    lip: np.ndarray, rim_centre: np.ndarray, rim_radius: float, tilt: float, done: bool
) -> dict[str, float]:
    """Potentials of the shaping terms ``aim``, ``upright`` and ``tilt``.

    Their changes over a step are the terms (potential-based shaping: the optimal policy
    is unchanged).

    Args:
        lip: the source's lip, m (world).
        rim_centre: the target's rim centre, m (world).
        rim_radius: the target's rim radius, m.
        tilt: the source's tilt, deg.
        done: poured plus in flight has reached the amount less the tolerance.
    """
    # The lip pours into the target from over the near half of its opening (the stream
    # leaves it moving towards +x, the way the source tilts).
    aim_at = rim_centre[:2] - np.array([AIM_OFFSET * rim_radius, 0.0])
    aim = -min(float(np.hypot(*(lip[:2] - aim_at))) / rim_radius, 10.0)
    tilt = tilt / 90.0
    return {"aim": aim, "upright": -tilt if done else 0.0, "tilt": 0.0 if done else tilt}


def outcome(info: Mapping) -> str:
    """Why a pouring episode ended as it did, from its last step's info.

    Returns:
        One of :data:`POUR_OUTCOMES`, the first that applies in its order.
    """
    if info["is_success"]:
        return "success"
    if info["spilled"] > 0:
        return "spilled"
    error = info["poured"] - info["target_amount"]
    if error > info["tolerance"]:
        return "overshot"
    if not info["poured_any"]:
        return "never_poured"
    if error < -info["tolerance"]:
        return "under_poured"
    return "unfinished"
