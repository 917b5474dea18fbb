"""A training curriculum over the env's own speed: an env argument changed at step counts.

Over the procedural family PPO finds the pour at Pour-v1's tilt of 60 deg/s in a few
hundred thousand steps, but learns a flick there; trained on at Pour-v2's 20 deg/s the
policy pours more slowly and stops closer to the amount, but from scratch at 20 deg/s its
training success rose to 0.11 at 200k steps and fell to 0 by 336k, where at 60 deg/s it
rose to 0.29 (docs/learning-from-reward.md, "Pour-v2"). The recipe key ``env_schedule``
lets a run train at one value first and the env's own later::

    env_schedule: {max_tilt_rate: [[0, 60], [600000, 20]]}

Each value holds from its step count (env steps over the whole run, resumed parts
included) to the next; before the first, the env's own. The callback sets it on every
training env before each rollout, so a resumed run is scheduled as an unbroken one. The
learning curve and the evaluation use the env as made (the id's defaults and the run's
``--env-kwargs``): they score the task, not the curriculum.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from pour_gym.errors import InputError

# The env arguments a schedule may change, and why each can: an argument read only when
# the env is made would be set in vain.
SCHEDULABLE = {
    "max_tilt_rate": "the source's fastest tilt, deg/s (read by every step)",
}


@dataclass(frozen=True)
class EnvSchedule:
    """The ``env_schedule`` key of a recipe: ``{argument: [[from_step, value], ...]}``.

    Attributes:
        name: the env argument (one of :data:`SCHEDULABLE`).
        points: ``(from_step, value)`` pairs, their steps increasing.
    """

    name: str
    points: tuple[tuple[int, float], ...]

    @classmethod
    def from_recipe(cls, value: dict) -> EnvSchedule:
        """From the recipe's mapping.

        Raises:
            InputError: not one schedulable argument, or its points not
                ``[[step, value], ...]`` with steps >= 0 increasing and values > 0.
        """
        if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in SCHEDULABLE:
            raise InputError(
                f"env_schedule is {{argument: [[from_step, value], ...]}} for one of "
                f"{', '.join(SCHEDULABLE)}, not {value!r}"
            )
        name, given = next(iter(value.items()))
        try:
            points = tuple((int(step), float(v)) for step, v in given)
        except (TypeError, ValueError):
            points = ()
        steps = [step for step, _ in points]
        if (
            not points
            or steps[0] < 0
            or any(b <= a for a, b in itertools.pairwise(steps))
            or not all(v > 0 for _, v in points)
        ):
            raise InputError(
                f"env_schedule's {name} needs [[from_step, value], ...] with steps >= 0 "
                f"increasing and values > 0, not {given!r}"
            )
        return cls(name, points)

    def value(self, step: int) -> float | None:
        """The argument's value at ``step`` (None before the first point: the env's own)."""
        now = None
        for start, v in self.points:
            if step >= start:
                now = v
        return now

    def to_dict(self) -> dict:
        """The recipe's form (for ``config.json``)."""
        return {self.name: [list(p) for p in self.points]}


def env_schedule_callback(schedule: EnvSchedule):
    """An SB3 callback that sets ``schedule``'s argument on every training env per rollout.

    Raises:
        InputError: at the start of training, for envs without the argument.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class ScheduleEnv(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.now: float | None = None

        def _on_training_start(self) -> None:
            try:
                self.training_env.get_attr(schedule.name)
            except AttributeError:
                raise InputError(
                    f"env_schedule sets {schedule.name}, which these envs do not have"
                ) from None

        def _on_rollout_start(self) -> None:
            value = schedule.value(self.num_timesteps)
            if value is None or value == self.now:
                return
            # Through the wrappers to the env that has the argument (gymnasium's
            # set_wrapper_attr); SubprocVecEnv's workers and the native env alike.
            self.training_env.env_method("set_wrapper_attr", schedule.name, value)
            self.now = value

        def _on_step(self) -> bool:
            return True

    return ScheduleEnv()
