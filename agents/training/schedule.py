"""What a recipe changes at step counts: an env argument, or an algorithm's.

Over the procedural family PPO finds the pour at Pour-v1's tilt of 60 deg/s in a few
hundred thousand steps, but learns a flick there; trained on at Pour-v2's 20 deg/s the
policy pours more slowly and stops closer to the amount, but from scratch at 20 deg/s its
training success rose to 0.11 at 200k steps and fell to 0 by 336k, where at 60 deg/s it
rose to 0.29 (docs/learning-from-reward.md, "Pour-v2"). The recipe key ``env_schedule``
lets a run train at one value first and the env's own later::

    env_schedule: {max_tilt_rate: [[0, 60], [500000, 20]]}

The two lineages that reached 0.62-0.66 over the family added PPO's ``target_kl`` only
once their pour was found; from the first update it stopped nearly every update after one
epoch, and two runs from scratch found the pour and lost it. ``algo_schedule`` sets an
algorithm's attribute the same way::

    algo_schedule: {target_kl: [[0, null], [500000, 0.03]]}

Each value holds from its step count (env steps over the whole run, resumed parts
included) to the next; before the first, the env's or the recipe's own. The callback sets
it before each rollout (the update after the rollout uses it), so a resumed run is
scheduled as an unbroken one. The learning curve and the evaluation use the env as made
(the id's defaults and the run's ``--env-kwargs``): they score the task, not the
curriculum.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from pour_gym.errors import InputError

# What a schedule may change, and why each can: an argument read only when the env or the
# algorithm is made would be set in vain. Each: (what it is, whether null is a value).
SCHEDULABLE = {
    "env_schedule": {
        "max_tilt_rate": ("the source's fastest tilt, deg/s (read by every step)", False),
    },
    "algo_schedule": {
        "target_kl": (
            "PPO's early stop of an update's epochs (read by every update; null: all epochs)",
            True,
        ),
    },
}


@dataclass(frozen=True)
class StepSchedule:
    """A recipe's ``env_schedule`` or ``algo_schedule``: ``{name: [[from_step, value], ...]}``.

    Attributes:
        key: the recipe key (``env_schedule`` or ``algo_schedule``).
        name: what it sets (one of :data:`SCHEDULABLE` ``[key]``).
        points: ``(from_step, value)`` pairs, their steps increasing.
    """

    key: str
    name: str
    points: tuple[tuple[int, float | None], ...]

    @classmethod
    def from_recipe(cls, key: str, value: dict) -> StepSchedule:
        """From the recipe's mapping under ``key``.

        Raises:
            InputError: not one schedulable name, or its points not ``[[step, value], ...]``
                with steps >= 0 increasing and values > 0 (or null where that is a value).
        """
        known = SCHEDULABLE[key]
        if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in known:
            raise InputError(
                f"{key} is {{name: [[from_step, value], ...]}} for one of "
                f"{', '.join(known)}, not {value!r}"
            )
        name, given = next(iter(value.items()))
        nullable = known[name][1]
        try:
            points = tuple(
                (int(step), None if v is None and nullable else float(v)) for step, v in given
            )
        except (TypeError, ValueError):
            points = ()
        steps = [step for step, _ in points]
        if (
            not points
            or steps[0] < 0
            or any(b <= a for a, b in itertools.pairwise(steps))
            or not all(v is None or v > 0 for _, v in points)
        ):
            null = " or null" if nullable else ""
            raise InputError(
                f"{key}'s {name} needs [[from_step, value], ...] with steps >= 0 "
                f"increasing and values > 0{null}, not {given!r}"
            )
        return cls(key, name, points)

    def point(self, step: int) -> tuple[int, float | None] | None:
        """The point in force at ``step`` (None before the first: the env's or recipe's own)."""
        now = None
        for start, v in self.points:
            if step >= start:
                now = (start, v)
        return now

    def to_dict(self) -> dict:
        """The recipe's form (for ``config.json``)."""
        return {self.name: [list(p) for p in self.points]}


def schedule_callback(schedule: StepSchedule):
    """An SB3 callback that sets ``schedule``'s value before each rollout.

    An ``env_schedule`` is set on every training env (through the wrappers; SubprocVecEnv's
    workers and the native vector env alike), an ``algo_schedule`` on the model.

    Raises:
        InputError: at the start of training, for envs or a model without the name.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    on_env = schedule.key == "env_schedule"

    class Schedule(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.now: tuple[int, float | None] | None = None

        def _on_training_start(self) -> None:
            if on_env:
                try:
                    self.training_env.get_attr(schedule.name)
                except AttributeError:
                    raise InputError(
                        f"env_schedule sets {schedule.name}, which these envs do not have"
                    ) from None
            elif not hasattr(self.model, schedule.name):
                raise InputError(
                    f"algo_schedule sets {schedule.name}, which "
                    f"{type(self.model).__name__} does not have"
                )

        def _on_rollout_start(self) -> None:
            point = schedule.point(self.num_timesteps)
            if point is None or point == self.now:
                return
            if on_env:
                # gymnasium's set_wrapper_attr reaches the env that has the argument.
                self.training_env.env_method("set_wrapper_attr", schedule.name, point[1])
            else:
                setattr(self.model, schedule.name, point[1])
            self.now = point

        def _on_step(self) -> bool:
            return True

    return Schedule()
