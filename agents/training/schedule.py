"""What a recipe changes at step counts: an env argument, or an algorithm's.

Over the procedural family PPO finds the pour at Pour-v1's tilt of 60 deg/s in a few
hundred thousand steps, but learns a flick there; trained on at Pour-v2's 20 deg/s the
policy pours more slowly and stops closer to the amount, but from scratch at 20 deg/s its
training success rose to 0.11 at 200k steps and fell to 0 by 336k, where at 60 deg/s it
rose to 0.29 (docs/learning-from-reward.md, "Pour-v2"). The recipe key ``env_schedule``
lets a run train at one value first and the env's own later::

    env_schedule: {max_tilt_rate: [[0, 60], [500000, 20]]}

A cost for each step (the reward's ``time_weight``) from a step count on, the env's own
weight (0 by default) before its first point::

    env_schedule: {time_weight: [[500000, 0.004]]}

The two lineages that reached 0.62-0.66 over the family added PPO's ``target_kl`` only
once their pour was found; from the first update it stopped nearly every update after one
epoch, and two runs from scratch found the pour and lost it. ``algo_schedule`` sets an
algorithm's attribute the same way::

    algo_schedule: {target_kl: [[0, null], [500000, 0.03]]}

A point's step may be ``switch`` instead of a count: it takes effect when the recipe's
``switch`` fires, at the first rollout from step ``earliest`` on at which SB3's training
success (the share of the last 100 episodes that succeeded) has reached ``success``, or at
step ``latest`` if it never does (:class:`SuccessSwitch`)::

    switch: {success: 0.3, earliest: 300000, latest: 800000}
    env_schedule: {max_tilt_rate: [[0, 60], [switch, 20]]}

A recipe may schedule several names under one key, each with its own points::

    algo_schedule: {target_kl: [[0, null], [500000, 0.03]], gamma: [[0, 0.99], [500000, 0.998]]}

The optimiser's step size may fall in steps (``learning_rate: [[0, 3.0e-4], [500000,
1.0e-4], [750000, 3.0e-5]]``): rl-zoo3's ``lin_X`` falls from the first update, this from
the points given.

The three seeds of the step-500k switch ended in the order of their training success at
the switch (0.14, 0.27, 0.14 gave 0.285, 0.405, 0.20 over the family), and the lineages
switched from a policy at 0.30. The step it fired at is kept in the run's
``switch.json``: a resumed run switches where the unbroken one did.

Each value holds from its step count (env steps over the whole run, resumed parts
included) to the next; before the first, the env's or the recipe's own. The callback sets
it before each rollout (the update after the rollout uses it), so a resumed run is
scheduled as an unbroken one. The learning curve and the evaluation use the env as made
(the id's defaults and the run's ``--env-kwargs``): they score the task, not the
curriculum.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pour_gym.errors import InputError

# A point's step that is the recipe's switch (SuccessSwitch), not a count.
SWITCH = "switch"
# Episodes SB3 keeps for its training success (ep_success_buffer): the switch waits for
# them all, so that its first reading is not of a few lucky episodes.
SUCCESS_WINDOW = 100

# What a schedule may change, and why each can: an argument read only when the env or the
# algorithm is made would be set in vain. Each: (what it is, whether null is a value, the
# largest value or None).
SCHEDULABLE = {
    "env_schedule": {
        "max_tilt_rate": ("the source's fastest tilt, deg/s (read by every step)", False, None),
        # Before a schedule's first point the env's own weight holds (0 by default), so a
        # cost from a step count on is [[from_step, weight]].
        "time_weight": ("the reward's cost for each step (read by every step)", False, None),
    },
    "algo_schedule": {
        "target_kl": (
            "PPO's early stop of an update's epochs (read by every update; null: all epochs)",
            True,
            None,
        ),
        "gamma": (
            "the discount (read by every update; PPO's rollout buffer's, for its advantages, "
            "set with it)",
            False,
            1.0,
        ),
        "learning_rate": (
            "the optimiser's step size (read by every update; the recipe's own, a number "
            "or rl-zoo3's lin_X, until the first point)",
            False,
            None,
        ),
    },
}


@dataclass(frozen=True)
class StepSchedule:
    """A recipe's ``env_schedule`` or ``algo_schedule``: ``{name: [[from_step, value], ...]}``.

    Attributes:
        key: the recipe key (``env_schedule`` or ``algo_schedule``).
        name: what it sets (one of :data:`SCHEDULABLE` ``[key]``).
        points: ``(from_step, value)`` pairs, their steps increasing; a step may be
            :data:`SWITCH` (once), the step at which the recipe's switch fires.
    """

    key: str
    name: str
    points: tuple[tuple[int | str, float | None], ...]

    @classmethod
    def from_recipe(cls, key: str, value: dict) -> StepSchedule:
        """From the recipe's mapping under ``key``.

        Raises:
            InputError: not one schedulable name, or its points not ``[[step, value], ...]``
                with steps >= 0 increasing (``switch`` at most once) and values > 0 (or
                null where that is a value).
        """
        known = SCHEDULABLE[key]
        if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in known:
            raise InputError(
                f"{key} is {{name: [[from_step, value], ...]}} for one of "
                f"{', '.join(known)}, not {value!r}"
            )
        name, given = next(iter(value.items()))
        _, nullable, largest = known[name]
        try:
            points = tuple(
                (
                    step if step == SWITCH else int(step),
                    None if v is None and nullable else float(v),
                )
                for step, v in given
            )
        except (TypeError, ValueError):
            points = ()
        steps = [step for step, _ in points if step != SWITCH]
        if (
            not points
            or sum(step == SWITCH for step, _ in points) > 1
            or points[0][0] == SWITCH
            or steps[0] < 0
            or any(b <= a for a, b in itertools.pairwise(steps))
            or not all(v is None or 0 < v <= (largest or np.inf) for _, v in points)
        ):
            null = " or null" if nullable else ""
            most = f" and <= {largest:g}" if largest else ""
            raise InputError(
                f"{key}'s {name} needs [[from_step, value], ...] with steps >= 0 "
                f"increasing (after a first count, one may be {SWITCH!r}) and values > "
                f"0{most}{null}, not {given!r}"
            )
        return cls(key, name, points)

    @classmethod
    def all_from_recipe(cls, key: str, value: dict) -> tuple[StepSchedule, ...]:
        """One schedule per name in the recipe's mapping under ``key``.

        ``algo_schedule: {target_kl: [[0, null], [500000, 0.03]], gamma: [[0, 0.99],
        [500000, 0.998]]}`` gives two, each set by its own callback.

        Raises:
            InputError: as :meth:`from_recipe`, for any of them, or an empty mapping.
        """
        if not isinstance(value, dict) or not value:
            return (cls.from_recipe(key, value),)  # refused there, with the form
        return tuple(cls.from_recipe(key, {name: points}) for name, points in value.items())

    @staticmethod
    def all_to_dict(schedules: tuple[StepSchedule, ...]) -> dict | None:
        """The recipe's form of several (for ``config.json``; None for none)."""
        return {k: v for x in schedules for k, v in x.to_dict().items()} or None

    @property
    def switched(self) -> bool:
        """Whether a point waits for the recipe's switch."""
        return any(step == SWITCH for step, _ in self.points)

    def point(self, step: int, switch_at: int | None = None) -> tuple[int, float | None] | None:
        """The point in force at ``step`` (None before the first: the env's or recipe's own).

        Args:
            step: env steps over the whole run.
            switch_at: the step the switch fired at; None while it has not (its point and
                those after it wait).
        """
        now = None
        for start, v in self.points:
            if start == SWITCH:
                if switch_at is None:
                    break
                start = switch_at
            if step >= start:
                now = (start, v)
        return now

    def to_dict(self) -> dict:
        """The recipe's form (for ``config.json``)."""
        return {self.name: [list(p) for p in self.points]}


@dataclass(frozen=True)
class SuccessSwitch:
    """A recipe's ``switch``: when its schedules' ``switch`` points take effect.

    At the first rollout from step ``earliest`` on at which SB3's training success (the
    share of the last :data:`SUCCESS_WINDOW` episodes that succeeded) is at least
    ``success``; at step ``latest`` if it has not been by then.

    Attributes:
        success: the training success that switches, in (0, 1].
        earliest: no switch before this step (env steps over the run).
        latest: the switch at this step if the success has not switched it.
    """

    success: float
    earliest: int
    latest: int

    @classmethod
    def from_recipe(cls, value: dict) -> SuccessSwitch:
        """From the recipe's ``switch`` mapping.

        Raises:
            InputError: not ``{success, earliest, latest}`` with 0 < success <= 1 and
                0 <= earliest <= latest.
        """
        try:
            made = cls(float(value["success"]), int(value["earliest"]), int(value["latest"]))
            if set(value) != {"success", "earliest", "latest"}:
                raise KeyError
        except (TypeError, KeyError, ValueError):
            made = None
        if made is None or not 0 < made.success <= 1 or not 0 <= made.earliest <= made.latest:
            raise InputError(
                "switch is {success: S, earliest: STEP, latest: STEP} with 0 < S <= 1 (the "
                f"training success that switches) and 0 <= earliest <= latest, not {value!r}"
            )
        return made

    def check(self, schedule: StepSchedule) -> None:
        """Refuse a schedule whose counted points could fall on the wrong side of the switch.

        Raises:
            InputError: a count before ``switch`` at or after ``earliest``, or one after it
                at or before ``latest``.
        """
        steps = [step for step, _ in schedule.points]
        if SWITCH not in steps:
            return
        at = steps.index(SWITCH)
        if any(step >= self.earliest for step in steps[:at]) or any(
            step <= self.latest for step in steps[at + 1 :]
        ):
            raise InputError(
                f"{schedule.key}'s {schedule.name} has counts that the switch (from "
                f"{self.earliest} to {self.latest}) could pass: counts before {SWITCH!r} "
                f"must be under {self.earliest}, counts after it over {self.latest}"
            )

    def to_dict(self) -> dict:
        """The recipe's form (for ``config.json``)."""
        return {"success": self.success, "earliest": self.earliest, "latest": self.latest}


class SwitchState:
    """Where a run's switch fired: None until it does; kept in ``switch.json``.

    Attributes:
        step: the env step it fired at (None: not yet).
        success: the training success it fired with (at ``latest``, over however many
            episodes SB3 held; None if none had ended).
    """

    FILE = "switch.json"

    def __init__(self, step: int | None = None, success: float | None = None) -> None:
        self.step = step
        self.success = success

    @classmethod
    def load(cls, out: Path) -> SwitchState:
        """A resumed run's switch (not fired if the run has no ``switch.json``)."""
        path = Path(out) / cls.FILE
        if not path.is_file():
            return cls()
        doc = json.loads(path.read_text())
        return cls(int(doc["step"]), doc["success"])

    def save(self, out: Path) -> None:
        """Write ``switch.json``."""
        doc = {"step": self.step, "success": self.success}
        (Path(out) / self.FILE).write_text(json.dumps(doc) + "\n")


def switch_callback(switch: SuccessSwitch, state: SwitchState, out: Path):
    """An SB3 callback that fires ``switch`` before a rollout, into ``state`` and ``out``.

    Put it before the schedules' callbacks: they read ``state`` at the same rollout start.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class Switch(BaseCallback):
        def _on_rollout_start(self) -> None:
            step = self.num_timesteps
            if state.step is not None or step < switch.earliest:
                return
            # SB3's record of the last episodes' is_success (emptied by a resume): read
            # only once full, and kept at the latest however many it holds.
            window = self.model.ep_success_buffer
            success = float(np.mean(window)) if len(window) else None
            full = len(window) >= SUCCESS_WINDOW
            if step >= switch.latest or (full and success >= switch.success):
                state.step, state.success = step, success
                state.save(out)
                self.logger.record("train/switch_step", step)

        def _on_step(self) -> bool:
            return True

    return Switch()


def schedule_callback(schedule: StepSchedule, switch: SwitchState | None = None):
    """An SB3 callback that sets ``schedule``'s value before each rollout.

    An ``env_schedule`` is set on every training env (through the wrappers; SubprocVecEnv's
    workers and the native vector env alike), an ``algo_schedule`` on the model. A
    ``switch`` point takes effect from the step in ``switch`` (:func:`switch_callback`).

    Raises:
        InputError: at the start of training, for envs or a model without the name, or
            for a schedule with a ``switch`` point given no switch.
    """
    if schedule.switched and switch is None:
        raise InputError(
            f"{schedule.key}'s {schedule.name} has a {SWITCH!r} point: the recipe needs a "
            "switch: {success: S, earliest: STEP, latest: STEP}"
        )
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
            point = schedule.point(self.num_timesteps, switch.step if switch else None)
            if point is None or point == self.now:
                return
            if on_env:
                # gymnasium's set_wrapper_attr reaches the env that has the argument.
                self.training_env.env_method("set_wrapper_attr", schedule.name, point[1])
            else:
                setattr(self.model, schedule.name, point[1])
                # PPO's advantages read the rollout buffer's gamma, copied when it was made.
                buffer = getattr(self.model, "rollout_buffer", None)
                if hasattr(buffer, schedule.name):
                    setattr(buffer, schedule.name, point[1])
                if schedule.name == "learning_rate":
                    # SB3's updates read the step size from lr_schedule (made from
                    # learning_rate when the model was), not from learning_rate itself.
                    self.model._setup_lr_schedule()
            self.now = point

        def _on_step(self) -> bool:
            return True

    return Schedule()
