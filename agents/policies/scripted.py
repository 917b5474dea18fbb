"""A scripted pouring policy for PourGym/Pour-v0 that reads only the warped features.

Move the lip over the near half of the target's opening, tilt quickly until fluid rises
above the lip (thesis f4 > 0), then slowly until it pours. While it pours, regulate the
flow by the tilt: the wanted flow is a fraction of what remains to be poured (never less
than a trickle), so the stream thins as the target amount comes near; tilt on while the
flow is below that, tilt back a little while it is above. Tilt back for good as soon as
the fluid poured plus the fluid in flight reaches the target amount less what will still
run out while tilting back (a fraction of the current flow). Because every quantity it
uses is relative to the containers' labelled geometry and to the target amount, the same
script pours from and into any container.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pour_gym.envs.actions import (
    LIP_CONTROLS,
    flow_action,
    flow_step,
    lip_action,
    tilt_action,
    untilt_rate,
)
from pour_gym.envs.pour_observation import FEATURE_NAMES
from pour_gym.envs.rules import running_rise
from pour_gym.errors import InputError

_I = {name: k for k, name in enumerate(FEATURE_NAMES)}
# The env's tilt forms the policy acts in: tilt_control="onset" names tilts from the
# source's onset, which the features do not give it. With "flow" it names the stream it
# wants and the env's regulator (the one it pours by in the other forms) holds it.
TILT_FORMS = ("rate", "angle", "flow")
# The policy's settings of the env's action form: its field -> the env's argument.
ACTION_SETTINGS = {
    "tilt_control": "tilt_control",
    "max_tilt_rate": "max_tilt_rate",
    "max_untilt_rate": "max_untilt_rate",
    "max_tilt": "max_tilt",
    "lip_control": "lip_control",
    "lip_speed": "max_speed",
}


def approach_lip(obs: np.ndarray, lip_offset: float, speed: float) -> tuple[np.ndarray, float]:
    """Move the lip towards its pouring point over the target, and down.

    A proportional approach (full speed beyond 3 cm) scaled by ``speed`` in [0, 1], so that
    a full source does not slosh over; down to the lowest allowed height.

    Args:
        obs: a features observation.
        lip_offset: the pouring point, in target rim radii before the rim centre.
        speed: the lip speed as an action in [0, 1].

    Returns:
        The action (tilt rate 0) and the lip's horizontal distance to the point, m.
    """
    r_t = obs[_I["target_rim_radius"]] * 0.1
    ex, ey = (obs[_I["lip_dx"]] - lip_offset) * r_t, obs[_I["lip_dy"]] * r_t
    action = np.zeros(4)
    action[:3] = np.clip([ex / 0.03, ey / 0.03, -1.0], -1.0, 1.0) * speed
    return action, float(np.hypot(ex, ey))


@dataclass
class ScriptedPourPolicy:
    """Pour by the features (``obs_mode="features"`` observations of Pour-v0).

    Flows are in target amounts per 0.1 s step, the unit the observation gives them in.

    Attributes:
        lip_offset: where the lip goes, in target rim radii before the rim centre (the
            stream leaves the lip moving towards the target's far side).
        position_tolerance: how close the lip must be before tilting, m.
        slow_rate: tilt rate while pouring, as an action in [0, 1].
        lead: steps' worth of the current flow that still run out after tilting back
            starts.
        share: the wanted flow per step as a share of what remains to be poured.
        min_flow: the least wanted flow (the trickle at the end), in target amounts per
            step; replaced by ``min_particles / amount`` when ``amount`` is known.
        gain: tilt action per relative flow error (wanted - flow) / wanted, in units of
            ``slow_rate``.
        back_rate: the fastest tilt back while regulating, as an action in [0, 1].
        max_speed: largest lip speed, as an action in [0, 1].
        amount: the target amount in particles, if the caller knows it (the features do
            not hold it); it turns the trickle into an absolute ``min_particles``.
        min_particles: the trickle, in particles per step, when ``amount`` is known.
        start_ramp: how much the lip speed may grow per step from rest, as an action (a
            gentle start, so that a full source does not slosh over; 1 or more: none).
            The ramp lives in the policy's memory, not in the observation: a learner
            imitating it cannot tell the first step from the tenth.
        tilt_control: the env's tilt action, ``"rate"`` (Pour-v0), ``"angle"``
            (Pour-v1) or ``"flow"`` (Pour-v5): the policy decides a rate and, for
            ``"angle"``, gives the tilt one step at that rate reaches (from the observed
            tilt), which the env moves to at the same rate; for ``"flow"`` it gives the
            flow it wants (its regulator is then the env's), and -1 to stand up.
            :func:`action_settings` reads it and the next four from an env id.
        max_tilt_rate: the env's ``max_tilt_rate``, deg/s (``"angle"`` only).
        max_untilt_rate: the env's ``max_untilt_rate``, deg/s (None: ``max_tilt_rate``):
            a negative action is a rate back at it.
        max_tilt: the env's ``max_tilt``, deg (``"angle"`` only).
        lip_control: the env's lip action, ``"velocity"`` or ``"target"``: the policy
            decides a velocity and, for ``"target"``, names the place one step at that
            velocity reaches along x and y (from the observed lip), and the lowest height
            (the policy only ever lowers the lip, and pours from the lowest height).
        lip_speed: the env's ``max_speed``, m/s (``"target"`` only).
        dt: the env's step, s (``"angle"`` and ``"target"`` only).
        tuned_tilt_rate: the ``max_tilt_rate`` (deg/s) at which ``slow_rate``,
            ``back_rate`` and ``lead`` hold as given. At another rate the policy keeps
            their meaning in deg/s and seconds: the slow rate scaled by
            ``tuned_tilt_rate / max_tilt_rate`` (at most 1, the fastest tilt), the back rate
            by ``tuned_tilt_rate`` over the rate back (``max_untilt_rate``), the lead by
            that ratio too (a slower tilt back lets more run out). Full-rate phases (to
            the lip's fluid, back for good) go as fast as the env allows.
    """

    lip_offset: float = 0.6
    position_tolerance: float = 0.004
    slow_rate: float = 0.06
    lead: float = 1.0
    share: float = 0.15
    min_flow: float = 0.02
    gain: float = 2.0
    back_rate: float = 0.3
    max_speed: float = 0.5
    amount: int | None = None
    min_particles: float = 1.5
    start_ramp: float = 0.1
    tilt_control: str = "rate"
    max_tilt_rate: float = 60.0
    max_untilt_rate: float | None = None
    max_tilt: float = 135.0
    lip_control: str = "velocity"
    lip_speed: float = 0.15
    dt: float = 0.1
    tuned_tilt_rate: float = 60.0

    def __post_init__(self) -> None:
        if self.tilt_control not in TILT_FORMS:
            raise InputError(
                f"the scripted policy acts with tilt_control {', '.join(TILT_FORMS)}, not "
                f"{self.tilt_control!r} (it cannot name a tilt from the source's onset)"
            )
        if self.lip_control not in LIP_CONTROLS:
            raise InputError(f"lip_control must be one of {LIP_CONTROLS}, not {self.lip_control!r}")
        if not self.max_tilt_rate > 0 or not self.tuned_tilt_rate > 0 or not self.untilt_rate > 0:
            raise InputError(
                "max_tilt_rate, max_untilt_rate and tuned_tilt_rate must be > 0 deg/s, not "
                f"{self.max_tilt_rate}, {self.max_untilt_rate} and {self.tuned_tilt_rate}"
            )
        self.reset()

    def tilt_rates(self) -> tuple[float, float, float]:
        """The slow and back rates as actions at the env's ``max_tilt_rate``, and the lead.

        The tuned rates keep their deg/s (within the env's fastest tilt) and the lead its
        seconds of tilting back: see ``tuned_tilt_rate``.

        Returns:
            (slow rate, back rate, lead in steps).
        """
        scale, back = (
            self.tuned_tilt_rate / self.max_tilt_rate,
            self.tuned_tilt_rate / self.untilt_rate,
        )
        return (
            min(self.slow_rate * scale, 1.0),
            min(self.back_rate * back, 1.0),
            self.lead * back,
        )

    @property
    def untilt_rate(self) -> float:
        """The env's fastest tilt back, deg/s."""
        return untilt_rate(self.max_tilt_rate, self.max_untilt_rate)

    def reset(self) -> None:
        """Forget the episode (call at every environment reset)."""
        self.phase = "move"
        self._last_out = 0.0
        self._speed = 0.0
        self._wanted: float | None = None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action for one features observation."""
        action = self._rate_action(np.asarray(obs, dtype=np.float64))
        if self.tilt_control == "flow":
            # The flow it wants, in the action's unit; none (upright) to move and to stop.
            wanted = self._wanted if self.phase == "tilt" else None
            action[3] = -1.0 if wanted is None else flow_action(wanted, self.dt)
        elif self.tilt_control == "angle":
            rate = self.max_tilt_rate if action[3] >= 0.0 else self.untilt_rate
            goal = 90.0 * obs[_I["tilt"]] + action[3] * rate * self.dt
            action[3] = np.clip(tilt_action(goal, self.max_tilt), -1.0, 1.0)
        if self.lip_control == "target":
            # Where one step at that velocity takes the lip, from the target's rim centre
            # (m), at the lowest height (z_min: 0 here).
            r_t = obs[_I["target_rim_radius"]] * 0.1
            lip = -np.array([obs[_I["lip_dx"]], obs[_I["lip_dy"]]], dtype=np.float64) * r_t
            goal = np.append(lip + action[:2] * self.lip_speed * self.dt, 0.0)
            action[:3] = np.clip(lip_action(goal, np.zeros(3), r_t, 0.0), -1.0, 1.0)
        return action

    def _rate_action(self, o: np.ndarray) -> np.ndarray:
        """The action with the tilt as a rate (Pour-v0's form)."""
        if self.phase == "move":
            # A gentle start, so that a full source does not slosh over.
            self._speed = min(self._speed + self.start_ramp, self.max_speed)
            action, distance = approach_lip(o, self.lip_offset, self._speed)
            if distance < self.position_tolerance:
                self.phase = "tilt"
            return action
        action = np.zeros(4)
        slow, back, lead = self.tilt_rates()
        # What has left the source, as a running most (a flickering particle counts once).
        out_now = o[_I["poured"]] + o[_I["in_flight"]] + o[_I["spilled"]]
        flow, out = running_rise(out_now, self._last_out)
        if self.phase == "tilt":
            self._last_out = out
            # The flow form names it (__call__ reads it while the phase is "tilt").
            self._wanted = self._want(out)
            if out + lead * flow >= 1.0:
                self.phase = "back"
            elif out <= 0.0:
                # Quickly to where the fluid reaches the lip, then slowly until it pours.
                action[3] = 1.0 if o[_I["f4_source"]] <= 0.0 else slow
            else:
                action[3] = flow_step(self._wanted, flow, slow, back, self.gain)
        if self.phase == "back":
            action[3] = -1.0
        return action

    def _want(self, out: float) -> float:
        """The flow wanted when ``out`` target amounts have left: a share of what remains."""
        trickle = self.min_particles / self.amount if self.amount else self.min_flow
        return max(trickle, self.share * (1.0 - out))


def action_settings(env_id: str, env_kwargs: dict | None = None) -> dict:
    """The action-form arguments of :class:`ScriptedPourPolicy` for an env id and its arguments.

    The env's ``tilt_control``, ``max_tilt_rate``, ``max_tilt``, ``lip_control`` and
    ``max_speed`` (as ``lip_speed``): its class's defaults, then the id's registered ones
    (Pour-v1's angle control), then ``env_kwargs``.
    """
    import inspect

    import gymnasium as gym

    from pour_gym.envs import register_envs
    from pour_gym.envs.pour import PourEnv

    register_envs()
    given = {**gym.spec(env_id).kwargs, **(env_kwargs or {})}
    defaults = inspect.signature(PourEnv).parameters
    return {
        mine: given.get(theirs, defaults[theirs].default)
        for mine, theirs in ACTION_SETTINGS.items()
    }
