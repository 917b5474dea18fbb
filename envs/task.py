"""What an environment's episodes are for, and how an episode is scored.

Every pour-gym environment class names its :class:`Task` (``env.unwrapped.task``, or
:func:`pour_gym.envs.task_of` for an id). Evaluation, learning curves, the soak and the
studies ask the task, not the info's keys, whether an env pours from a source into a
target and what an episode's metrics are, so that one definition of each metric serves
them all.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pour_gym.envs.rules import POUR_OUTCOMES, out_of_source, outcome


@dataclass(frozen=True)
class Task:
    """A kind of episode and its metrics.

    Attributes:
        name: ``"pour"``, ``"drop"`` or ``"tilt"``.
        pours: whether an episode pours from a source container into a target one (its
            env takes ``source_objects`` and ``target_objects``, its info counts the
            particles); otherwise an episode has one container (``objects``).
        summary: one line on what an episode asks.
    """

    name: str
    pours: bool
    summary: str

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The keys of :meth:`metrics`, in order."""
        names = ("success", "return")
        if self.pours:
            names += ("amount_error", "spilled")
        return names

    def metrics(self, info: dict, episode_return: float) -> dict[str, float]:
        """An episode's scores from its last step's info and its return.

        Args:
            info: the info of the episode's last step.
            episode_return: the sum of the episode's rewards.

        Returns:
            ``success`` (1 or 0) and ``return``; a pouring task adds ``amount_error``
            (|poured - target amount|, particles) and ``spilled`` (particles).
        """
        out = {"success": float(bool(info["is_success"])), "return": float(episode_return)}
        if self.pours:
            out["amount_error"] = float(abs(info["poured"] - info["target_amount"]))
            out["spilled"] = float(info["spilled"])
        return out

    @property
    def outcomes(self) -> tuple[str, ...]:
        """The names :meth:`outcome` returns (empty for a task with none)."""
        return tuple(POUR_OUTCOMES) if self.pours else ()

    def outcome(self, info: dict) -> str | None:
        """Why a pouring episode ended as it did, from its last step's info.

        Returns:
            One of :data:`POUR_OUTCOMES` (the first that applies, in its order); None for
            a task that does not pour.
        """
        return outcome(info) if self.pours else None

    def outcome_shares(self, infos) -> dict[str, float]:
        """The share of episodes (their last infos) per outcome, as ``outcome_<name>``."""
        found = [self.outcome(info) for info in infos]
        n = max(len(found), 1)
        return {f"outcome_{name}": found.count(name) / n for name in self.outcomes}

    def diagnostics(self, info: dict) -> dict[str, float]:
        """What an episode says about the simulation rather than the policy.

        Returns:
            A pouring task: ``corrections`` (particles the fluid put back out of a wall
            they had tunnelled into in the last step); the others: nothing.
        """
        return {"corrections": float(info["fluid_corrections"])} if self.pours else {}

    def profile(self, infos: Sequence[Mapping], dt: float) -> dict[str, float]:
        """How a pouring episode poured, from every step's info (:func:`pour_profile`).

        Returns:
            A pouring task: ``pour_seconds`` and ``peak_flow``; the others: nothing.
        """
        return pour_profile(infos, dt) if self.pours else {}


def pour_profile(infos: Sequence[Mapping], dt: float) -> dict[str, float]:
    """How long a pour's stream ran and how fast it ran at most.

    What has left the source is counted as a running maximum (a particle flickering
    across the lip counts once), so a flow is never negative.

    Args:
        infos: every step's info of a pouring episode, in order.
        dt: the env's step, s.

    Returns:
        ``pour_seconds``: from the start of the first step that let particles out of the
        source to the end of the last, s (0 if none left); ``peak_flow``: the most that
        left in one step, in target amounts per second.
    """
    if not infos:
        return {"pour_seconds": 0.0, "peak_flow": 0.0}
    out = np.maximum.accumulate([out_of_source(info) for info in infos])
    flow = np.diff(out, prepend=0)
    steps = np.flatnonzero(flow > 0)
    seconds = float((steps[-1] - steps[0] + 1) * dt) if len(steps) else 0.0
    return {
        "pour_seconds": seconds,
        "peak_flow": float(flow.max() / infos[-1]["target_amount"] / dt),
    }


def mean_metrics(episodes: Iterable[dict[str, float]]) -> dict[str, float]:
    """The mean of each metric over episodes (the keys of the first)."""
    episodes = list(episodes)
    if not episodes:
        raise ValueError("no episodes to average")
    return {key: float(np.mean([e[key] for e in episodes])) for key in episodes[0]}


POUR = Task(
    "pour",
    pours=True,
    summary="pour a target amount from a held container into another, spilling nothing",
)
DROP = Task(
    "drop",
    pours=False,
    summary="predict whether a released particle ends up in the container (experiment 1)",
)
TILT = Task(
    "tilt",
    pours=False,
    summary="predict whether a filled container tilted to an angle pours (experiment 2)",
)
