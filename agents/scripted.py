"""A scripted pouring policy for PourGym/Pour-v0 that reads only the warped features.

Move the lip over the near half of the target's opening, tilt quickly until fluid rises
above the lip (thesis f4 > 0), then slowly while it pours, and tilt back as soon as the
fluid poured plus the fluid in flight reaches the target amount less what will still run
out while tilting back (a fraction of the amount, estimated from the flow at that moment).
Because every quantity it uses is relative to the containers' labelled geometry, the same
script pours from and into any container.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pour_gym.envs.pour import FEATURE_NAMES

_I = {name: k for k, name in enumerate(FEATURE_NAMES)}


@dataclass
class ScriptedPourPolicy:
    """Pour by the features (``obs_mode="features"`` observations of Pour-v0).

    Attributes:
        lip_offset: where the lip goes, in target rim radii before the rim centre (the
            stream leaves the lip moving towards the target's far side).
        position_tolerance: how close the lip must be before tilting, m.
        slow_rate: tilt rate while pouring, as an action in [0, 1].
        flow: the flow, in target amounts per step, above which the tilt is held.
        max_speed: largest lip speed, as an action in [0, 1].
        lead: steps' worth of the current flow that still runs out after tilting back
            starts (measured on the red cup: 1-2).
    """

    lip_offset: float = 0.6
    position_tolerance: float = 0.004
    slow_rate: float = 0.12
    lead: float = 1.5
    flow: float = 0.04
    max_speed: float = 0.5

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the episode (call at every environment reset)."""
        self.phase = "move"
        self._last_out = 0.0
        self._speed = 0.0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action for one features observation."""
        o = np.asarray(obs, dtype=np.float64)
        r_t = o[_I["target_rim_radius"]] * 0.1
        action = np.zeros(4)
        if self.phase == "move":
            ex = (o[_I["lip_dx"]] - self.lip_offset) * r_t
            ey = o[_I["lip_dy"]] * r_t
            # A proportional approach at up to half the speed limit, and a gentle start,
            # so that a full source does not slosh over; down to the lowest height.
            self._speed = min(self._speed + 0.1, self.max_speed)
            action[0] = np.clip(ex / 0.03, -1.0, 1.0) * self._speed
            action[1] = np.clip(ey / 0.03, -1.0, 1.0) * self._speed
            action[2] = -self._speed
            if np.hypot(ex, ey) < self.position_tolerance:
                self.phase = "tilt"
            return action
        out = o[_I["poured"]] + o[_I["in_flight"]] + o[_I["spilled"]]
        if self.phase == "tilt":
            flow = out - self._last_out  # fraction of the amount per step
            self._last_out = out
            if out + self.lead * flow >= 1.0:
                self.phase = "back"
            elif o[_I["f4_source"]] <= 0.0 and out <= 0.0:
                action[3] = 1.0
            elif flow < self.flow:
                # Tilt on while the flow is gentle, hold while it is strong: a thin
                # stream lands where it is aimed and stops soon after tilting back.
                action[3] = self.slow_rate
        if self.phase == "back":
            action[3] = -1.0
        return action
