"""Training-only reward terms: credit for a pour that ends near its amount.

Pour-v1's reward pays for the amount in two ways: the poured particles up to the target
amount T and back down beyond it (a tent whose slope is 1/T a particle), and the success
bonus, all or nothing at the tolerance (10 % of T). Between the two, a pour that stops 15 %
short and one that stops 11 % short earn nearly the same: the bonus is missed either way
and the tent differs by 0.04. Over the family the failures left are mostly there
(docs/learning-from-reward.md: over- and under-pouring a third of the episodes). The
wrapper here adds a graded term on an episode's last step, so a near miss earns more than a
far one and the learner is told which way the amount lies even when it fails.

The env's task, its success and the curves' scores stay the env's own: this is a
recipe's wrapper (``env_wrapper``), like the curricula, and SB3's ``Monitor`` inside it
records the env's reward.
"""

from __future__ import annotations

import gymnasium as gym

from pour_gym.envs.rules import UPRIGHT_DEG


def closeness(poured: int, target_amount: int, tol: int, width: float) -> float:
    """How near a finished pour came to its amount: 1 on it, 0 from ``width`` tolerances off.

    Args:
        poured: particles in the target.
        target_amount: particles.
        tol: the episode's tolerance, particles.
        width: the error, in tolerances, at which the credit reaches 0.

    Returns:
        ``max(0, 1 - |poured - target_amount| / (width * tol))``.
    """
    return max(0.0, 1.0 - abs(poured - target_amount) / (width * tol))


class AmountCloseness(gym.Wrapper):
    """Pour: on an episode's last step, ``weight`` times how near the pour came to its amount.

    Paid only on a step that ends the episode (``terminated``) with nothing spilled, the
    source upright and no holder failure: a pour that spilled or was cut short earns
    nothing here, so the term does not pay for ending an episode any other way. Within the
    tolerance it adds to the env's success bonus (a closer pour earns more, as the
    expert's does); beyond it the credit falls linearly to 0 at ``width`` tolerances.

    Args:
        env: a Pour env (possibly wrapped).
        weight: the term's weight, in the env's reward units.
        width: the error, in tolerances, at which the credit reaches 0.
    """

    def __init__(self, env: gym.Env, weight: float = 2.0, width: float = 3.0):
        super().__init__(env)
        if not weight >= 0 or not width > 0:
            raise ValueError(
                f"AmountCloseness needs weight >= 0 and width > 0, not {weight}, {width}"
            )
        self.weight = float(weight)
        self.width = float(width)

    def step(self, action):
        """The env's step, its reward plus the term on an episode's last step."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if (
            terminated
            and info["spilled"] == 0
            and info["tilt_deg"] < UPRIGHT_DEG
            and not info.get("failure")
        ):
            term = closeness(info["poured"], info["target_amount"], info["tolerance"], self.width)
            info = {**info, "closeness": term}
            reward = float(reward) + self.weight * term
        return obs, reward, terminated, truncated, info
