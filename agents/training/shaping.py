"""Training-only reward terms: credit for a near miss, a charge for an unstoppable flow.

Pour-v1's reward pays for the amount in two ways: the poured particles up to the target
amount T and back down beyond it (a tent whose slope is 1/T a particle), and the success
bonus, all or nothing at the tolerance (10 % of T). Between the two, a pour that stops 15 %
short and one that stops 11 % short earn nearly the same: the bonus is missed either way
and the tent differs by 0.04. Over the family the failures left are mostly there
(docs/learning-from-reward.md: over- and under-pouring a third of the episodes). The
wrapper here adds a graded term on an episode's last step, so a near miss earns more than a
far one and the learner is told which way the amount lies even when it fails. A second
(:class:`FlowLimit`) charges, on the step it happens, a stream running faster than the
pour could still be stopped on its amount.

The env's task, its success and the curves' scores stay the env's own: this is a
recipe's wrapper (``env_wrapper``), like the curricula, and SB3's ``Monitor`` inside it
records the env's reward.
"""

from __future__ import annotations

import gymnasium as gym

from pour_gym.envs.rules import UPRIGHT_DEG, out_of_source


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


def excess_flow(out: int, last_out: int, target_amount: int, lead: float) -> float:
    """How much faster than it can be stopped a pour ran over a step, in target amounts.

    Once the source starts tilting back, what is in flight and what still runs over the
    lip lands too: about ``lead`` steps of the current flow. A flow above what remains
    over ``lead`` cannot be stopped on the amount.

    Args:
        out: particles out of the source (poured, in flight, spilled) after the step.
        last_out: the same before it.
        target_amount: particles.
        lead: steps of flow that still land after the source starts back.

    Returns:
        ``max(0, flow - max(remaining, 0) / lead)``, flow and remaining over T.
    """
    t = target_amount
    flow, remaining = (out - last_out) / t, (t - last_out) / t
    return max(0.0, flow - max(remaining, 0.0) / lead)


class FlowLimit(gym.Wrapper):
    """Pour: a charge, per step, for a flow the pour could not stop on its amount.

    The env pays the amount when the pour ends (landed particles, the success bonus),
    decided by whether the source stood up in time: a stream too fast for what remains
    overshoots whatever the learner does next, and the learner hears of it only when the
    particles land. This term charges ``weight`` times :func:`excess_flow` on every step,
    with what has left the source counted as a running maximum (a particle flickering
    across the lip counts once), so a pour that runs too fast near its end is told on
    the step it does. A pour slowed to stop on its amount pays nothing; the term's only
    parameter is ``lead``, how many steps of flow still land after the source starts back.

    Args:
        env: a Pour env (possibly wrapped).
        weight: the term's weight, in the env's reward units.
        lead: steps of flow (0.1 s each) that still land after the source starts back.
    """

    def __init__(self, env: gym.Env, weight: float = 1.0, lead: float = 5.0):
        super().__init__(env)
        if not weight >= 0 or not lead > 0:
            raise ValueError(f"FlowLimit needs weight >= 0 and lead > 0, not {weight}, {lead}")
        self.weight = float(weight)
        self.lead = float(lead)
        self._out = 0

    def reset(self, **kwargs):
        """The env's reset."""
        obs, info = self.env.reset(**kwargs)
        self._out = out_of_source(info)
        return obs, info

    def step(self, action):
        """The env's step, its reward less the charge (``info["reward_flow_limit"]``)."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        out = max(self._out, out_of_source(info))
        term = -self.weight * excess_flow(out, self._out, info["target_amount"], self.lead)
        self._out = out
        info = {**info, "reward_flow_limit": term}
        return obs, float(reward) + term, terminated, truncated, info
