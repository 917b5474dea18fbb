"""Exploration noise shrunk over the end of a run, so the finished policy is tuned to its mean.

A PPO policy learns where to stop pouring while its own Gaussian noise acts: the noisy pour
runs on a little longer (or spills a little more), so the mean action, the one a finished
policy is scored by, stops elsewhere (docs/learning-from-reward.md, "Why the mean action
pours less than the samples"). The recipe key ``noise_schedule`` caps the policy's action
noise from one step count on, the cap shrinking geometrically to a final standard
deviation at the run's last step; the policy keeps learning under the smaller noise, so
what it learns last is learnt for (nearly) the action it will be scored by.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pour_gym.errors import InputError


@dataclass(frozen=True)
class NoiseSchedule:
    """The ``noise_schedule`` key of a recipe: ``{start: steps, std: final std}``.

    Attributes:
        start: the step count from which the noise is capped (env steps, counted over the
            whole run, resumed parts included).
        std: the action noise's standard deviation at the run's last step (the policy's
            ``exp(log_std)``, in action units; for gSDE, of its noise weights).
    """

    start: int
    std: float

    @classmethod
    def from_recipe(cls, value: dict) -> NoiseSchedule:
        """From the recipe's mapping.

        Raises:
            InputError: missing or unknown keys, a negative start, a std not above 0.
        """
        if not isinstance(value, dict) or set(value) != {"start", "std"}:
            raise InputError(f"noise_schedule is {{start: steps, std: final std}}, not {value!r}")
        start, std = int(value["start"]), float(value["std"])
        if start < 0 or not std > 0:
            raise InputError(
                f"noise_schedule needs start >= 0 and std > 0, not start={start}, std={std}"
            )
        return cls(start, std)

    def cap(self, step: int, total: int) -> float | None:
        """The largest log standard deviation at ``step`` of a run that ends at ``total``.

        Falls geometrically from 1 (the action's half-range: no cap on a policy that
        explores at all sensibly) at ``start`` to ``std`` at ``total``; None before
        ``start``. A function of the step alone, so a resumed run is capped as an
        unbroken one.
        """
        if step < self.start:
            return None
        frac = min((step - self.start) / max(total - self.start, 1), 1.0)
        return frac * math.log(self.std)


def noise_callback(schedule: NoiseSchedule, total: int):
    """An SB3 callback that caps a policy's ``log_std`` by ``schedule`` before each rollout.

    Args:
        schedule: the recipe's schedule.
        total: the step count the run ends at.

    Raises:
        InputError: at the start of training, for a policy with no ``log_std`` (SAC's and
            TQC's noise is set by their entropy coefficient, not a parameter).
    """
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    class CapNoise(BaseCallback):
        def _on_training_start(self) -> None:
            if not isinstance(getattr(self.model.policy, "log_std", None), torch.nn.Parameter):
                raise InputError(
                    f"noise_schedule caps a policy's log_std (PPO, A2C); "
                    f"{type(self.model).__name__}'s policy has none"
                )

        def _on_rollout_start(self) -> None:
            cap = schedule.cap(self.num_timesteps, total)
            if cap is None:
                return
            log_std = self.model.policy.log_std
            with torch.no_grad():
                log_std.clamp_(max=cap)
            if self.model.use_sde:  # the noise weights are drawn from log_std
                self.model.policy.reset_noise(self.training_env.num_envs)

        def _on_step(self) -> bool:
            return True

    return CapNoise()
