"""How the pouring env's actions are encoded, and the source's motion they command.

The forms of the tilt action (a rate, an angle, a tilt from the source's onset, a stream
to pour) and of the lip action (a velocity, a place in the target's terms), the limits
they are checked against, and the step each takes from where the source is: pure
functions that :class:`~pour_gym.envs.pour.PourEnv` moves the source by and the scripted
policy and its demonstrations write their actions with (each encoding defined once, with
its inverse).
"""

from __future__ import annotations

import numpy as np

from pour_gym.errors import InputError

# The forms of the tilt action (the fourth) and of the lip action (the first three).
TILT_CONTROLS = ("rate", "angle", "onset", "flow")
LIP_CONTROLS = ("velocity", "target")
# tilt_control="angle": the action's tilt range reaches this far below upright (deg), so a
# band of actions, not one value, sets the source upright.
UPRIGHT_BAND = 20.0
# tilt_control="onset": how far beyond the source's onset tilt action 1 names (deg).
ONSET_REACH = 30.0
# tilt_control="flow": actions from FLOW_STOP to 1 ask for a flow from 0 to FLOW_REACH
# target amounts per second (action 0: a third of it, about the stream the scripted expert
# pours, so that exploring actions pour), actions at or below FLOW_STOP stand the source
# up; the regulator that holds the flow is the scripted expert's, in deg/s: at most
# FLOW_TILT_RATE on while the flow is short, at most FLOW_BACK_RATE back while it is
# over, the tilt's change FLOW_GAIN x that rate x the relative error.
FLOW_STOP = -0.5
FLOW_REACH = 1.5
FLOW_TILT_RATE = 3.6
FLOW_BACK_RATE = 18.0
FLOW_GAIN = 2.0

# lip_control="target": the lip's goal reaches this many target rim radii from the target's
# rim centre along x and y, and rises this high above the lowest allowed lip height (m).
LIP_REACH = 2.0
LIP_RISE = 0.1


def check_motion(
    max_speed: float,
    max_tilt_rate: float,
    max_tilt: float,
    tilt_control: str,
    lip_control: str,
    max_untilt_rate: float | None = None,
    stand_below: float | None = None,
) -> None:
    """Check the source's motion arguments (see ``PourEnv``; the last two may be None).

    Raises:
        InputError: a speed or rate not above 0, a largest tilt outside (0, 180] deg, an
            unknown form of the tilt or lip action (named, with the forms there are), or a
            ``stand_below`` outside (0, 1] or with ``tilt_control="rate"``.
    """
    rates = [("max_speed", max_speed), ("max_tilt_rate", max_tilt_rate)]
    if max_untilt_rate is not None:
        rates.append(("max_untilt_rate", max_untilt_rate))
    for name, value in rates:
        if not value > 0:
            raise InputError(f"{name} must be positive, not {value}")
    if not 0 < max_tilt <= 180:
        raise InputError(f"max_tilt must be in (0, 180] degrees, not {max_tilt}")
    if tilt_control not in TILT_CONTROLS:
        raise InputError(f"tilt_control must be one of {TILT_CONTROLS}, not {tilt_control!r}")
    if lip_control not in LIP_CONTROLS:
        raise InputError(f"lip_control must be one of {LIP_CONTROLS}, not {lip_control!r}")
    if stand_below is not None:
        if not 0 < stand_below <= 1:
            raise InputError(
                f"stand_below is a fraction of the onset tilt in (0, 1], not {stand_below}"
            )
        if tilt_control in ("rate", "flow"):
            raise InputError(
                "stand_below applies to the tilts an action names: give tilt_control="
                f"'angle' or 'onset' with it (a {tilt_control!r} action names no tilt; "
                f"a 'flow' action at or below {FLOW_STOP} stands the source up)"
            )


def tilt_goal(action: float, max_tilt: float) -> float:
    """The tilt (deg) an angle action in [-1, 1] names: -``UPRIGHT_BAND`` to ``max_tilt``."""
    return -UPRIGHT_BAND + 0.5 * (action + 1.0) * (max_tilt + UPRIGHT_BAND)


def tilt_action(goal: float, max_tilt: float) -> float:
    """The angle action naming a tilt (deg): :func:`tilt_goal`'s inverse, not clipped."""
    return 2.0 * (goal + UPRIGHT_BAND) / (max_tilt + UPRIGHT_BAND) - 1.0


def onset_tilt(held: np.ndarray, fill: float) -> float:
    """The tilt (deg) at which a fill reaches the source's mouth: where it starts to pour.

    Quasi-static: the tilt at which what the source holds at rest falls to the fill
    (interpolated between whole degrees); 0 for a fill above what it holds upright, the
    last tilt of ``held`` for one it holds at every tilt.

    Args:
        held: what the source holds at rest at tilts 0, 1, 2, ... deg, particles
            (:func:`pour_gym.features.mouth_volume` over the particle volume).
        fill: the fluid in the source, particles.
    """
    # Never more at a larger tilt: the voxelised cavity can add a voxel here and there.
    held = np.minimum.accumulate(np.asarray(held, dtype=np.float64))
    tilts = np.arange(len(held), dtype=np.float64)
    return float(np.interp(fill, held[::-1], tilts[::-1]))


def untilt_rate(max_tilt_rate: float, max_untilt_rate: float | None) -> float:
    """The fastest tilt back towards upright, deg/s (``max_untilt_rate``, None: on's)."""
    return max_tilt_rate if max_untilt_rate is None else max_untilt_rate


def needs_onset(control: str, stand_below: float | None) -> bool:
    """Whether the tilt action reads the source's onset (what it holds by tilt).

    The ``"onset"`` form names tilts from it, and ``stand_below`` compares goals with it.
    """
    return control in ("onset", "flow") or stand_below is not None


def flow_step(wanted: float, flow: float, on: float, back: float, gain: float = FLOW_GAIN) -> float:
    """The regulator of a stream by the tilt: the change (in ``on``'s unit) for one step.

    Tilt on while the flow is short of the wanted one, back while it is over, by ``gain``
    x ``on`` x the relative error, within [-``back``, ``on``]. The scripted expert pours by
    it, and the ``tilt_control="flow"`` action is held by it.

    Args:
        wanted: the flow wanted, > 0 (any unit; ``flow`` in the same).
        flow: the flow of the last step.
        on: the largest change on (towards pouring), >= 0.
        back: the largest change back, >= 0.
        gain: the change per relative error, in units of ``on``.
    """
    return float(np.clip(gain * on * (wanted - flow) / wanted, -back, on))


def next_tilt(
    control: str, action: float, tilt: float, most: float, max_tilt: float,
    held: np.ndarray | None = None, fill: float = 0.0, back: float | None = None,
    stand_below: float | None = None, flow: float = 0.0, dt: float = 0.1,
) -> float:  # fmt: skip
    """Where a tilt action takes the source's tilt (deg) in one step.

    Args:
        control: the env's ``tilt_control``: ``"rate"`` (the action times ``most``),
            ``"angle"`` (towards :func:`tilt_goal`), ``"onset"`` (towards
            :func:`onset_goal`, the onset from ``held`` and ``fill``) or ``"flow"``
            (:func:`flow_tilt`).
        action: the tilt action, in [-1, 1].
        tilt: the tilt now, deg.
        most: the largest change in one step, deg (towards ``max_tilt``).
        max_tilt: the largest tilt, deg.
        held: ``"onset"``: what the source holds by tilt (:func:`onset_tilt`), particles.
        fill: ``"onset"``: the fluid in the source, particles.
        back: the largest change back towards upright in one step, deg (None: ``most``).
        stand_below: ``"angle"`` and ``"onset"``: a goal below this fraction of the onset
            (from ``held`` and ``fill``) is upright (None: every goal as named).
            ``PourEnv`` passes it once the episode's pour has begun, None before.
        flow: ``"flow"``: the last step's flow out of the source, target amounts.
        dt: ``"flow"``: the step, s.

    Returns:
        The tilt, within [0, ``max_tilt``].

    Raises:
        InputError: ``stand_below``, the onset or the flow form without ``held``.
    """
    onset_needed = needs_onset(control, stand_below)
    if held is None and onset_needed:
        raise InputError(
            "the onset and flow forms and stand_below need held (what the source holds)"
        )
    back = most if back is None else back
    if control == "rate":
        tilt = tilt + action * (most if action >= 0.0 else back)
    elif control == "flow":
        tilt = flow_tilt(action, tilt, onset_tilt(held, fill), flow, most, back, dt)
    else:
        # The onset (an interpolation over the tilts) only where the action needs it.
        onset = onset_tilt(held, fill) if onset_needed else None
        if control == "angle":
            goal = tilt_goal(action, max_tilt)
        else:
            goal = onset_goal(action, onset, max_tilt)
        if stand_below is not None and goal < stand_below * onset:
            # Well below the onset nothing pours: holding there only waits, and a finished
            # pour stands up (a held tilt short of upright leaves the episode unfinished).
            goal = 0.0
        tilt = tilt + np.clip(goal - tilt, -back, most)
    return float(np.clip(tilt, 0.0, max_tilt))


def flow_tilt(
    action: float, tilt: float, onset: float, flow: float, most: float, back: float, dt: float
) -> float:
    """Where a ``tilt_control="flow"`` action takes the tilt (deg) in one step, unclipped.

    An action at or below ``FLOW_STOP`` wants no flow: the source tilts back to upright at
    ``back``. Above it, it wants :func:`flow_wanted` target amounts: with nothing flowing
    below the onset the source tilts to it at up to ``most`` (quickly to where a stream
    begins, as a person does), and then :func:`flow_step` regulates (at most
    ``FLOW_TILT_RATE`` on, ``FLOW_BACK_RATE`` back), so that the stream follows the one
    the action names from any source at any fill (behind it while the onset rises as the
    source empties: 0.57-0.81 of it over the first 3 s on the red cup).

    Args:
        action: the tilt action, in [-1, 1].
        tilt: the tilt now, deg.
        onset: the source's onset now (:func:`onset_tilt`), deg.
        flow: the last step's flow out of the source, target amounts.
        most: the largest change on in one step, deg.
        back: the largest change back in one step, deg.
        dt: the step, s.
    """
    wanted = flow_wanted(action, dt)
    if wanted <= 0.0:
        return tilt - min(back, tilt)
    on = FLOW_TILT_RATE * dt
    if flow <= 0.0 and tilt < onset:
        return tilt + min(most, max(onset - tilt, on))
    return tilt + flow_step(wanted, flow, on, min(FLOW_BACK_RATE * dt, back))


def flow_wanted(action: float, dt: float) -> float:
    """The flow a ``tilt_control="flow"`` action asks for, target amounts per step of ``dt`` s.

    0 at or below ``FLOW_STOP``, ``FLOW_REACH`` x ``dt`` at 1, linear between.
    """
    return max(action - FLOW_STOP, 0.0) / (1.0 - FLOW_STOP) * FLOW_REACH * dt


def flow_action(wanted: float, dt: float) -> float:
    """The ``tilt_control="flow"`` action asking for a flow (target amounts per step), <= 1.

    :func:`flow_wanted`'s inverse; a flow beyond the action's reach asks for the most.
    """
    return min(FLOW_STOP + (1.0 - FLOW_STOP) * wanted / (FLOW_REACH * dt), 1.0)


def onset_goal(action: float, onset: float, max_tilt: float) -> float:
    """The tilt (deg) a ``tilt_control="onset"`` action in [-1, 1] names.

    From -1 to 0 the tilt runs from -``UPRIGHT_BAND`` to ``onset`` (nothing pours), from 0
    to 1 from ``onset`` to ``ONSET_REACH`` beyond it (at most ``max_tilt``): one action
    means the same stage of a pour from every source and fill.
    """
    if action <= 0.0:
        return -UPRIGHT_BAND + (action + 1.0) * (onset + UPRIGHT_BAND)
    return min(onset + action * ONSET_REACH, max_tilt)


def next_lip(
    action: np.ndarray,
    lip: np.ndarray,
    z_min: float,
    max_speed: float,
    dt: float,
    goal: np.ndarray | None,
) -> np.ndarray:
    """Where the lip goes in a step of ``dt`` s: at most ``max_speed`` m/s along each axis.

    Args:
        action: the lip's three actions; with no ``goal``, a velocity (times ``max_speed``).
        lip: where the lip is, m.
        z_min: the lowest the lip may go (the source clears the target's rim), m.
        max_speed: the lip's speed at action 1, m/s.
        dt: the step, s.
        goal: where ``lip_control="target"`` sends it (:func:`lip_goal`), or None.

    Returns:
        The lip's next place, in the box over the table (x -0.1 to 0.45 m, y -0.3 to 0.3,
        z ``z_min`` to 0.5).
    """
    if goal is None:
        move = action * max_speed * dt  # in this order: Pour-v0's bits
    else:
        reach = max_speed * dt
        move = np.clip(goal - lip, -reach, reach)
    return np.clip(lip + move, np.array([-0.1, -0.3, z_min]), np.array([0.45, 0.3, 0.5]))


def lip_goal(
    action: np.ndarray, rim_centre: np.ndarray, rim_radius: float, z_min: float
) -> np.ndarray:
    """The lip position (m, world) a ``lip_control="target"`` action in [-1, 1]^3 names.

    Along x and y, the target's rim centre plus the action times ``LIP_REACH`` rim radii;
    up, from ``z_min`` (action -1) to ``LIP_RISE`` above it (action 1).
    """
    a = np.asarray(action, dtype=np.float64)
    xy = np.asarray(rim_centre, dtype=np.float64)[:2] + a[:2] * LIP_REACH * rim_radius
    return np.array([xy[0], xy[1], z_min + 0.5 * (a[2] + 1.0) * LIP_RISE])


def lip_action(
    goal: np.ndarray, rim_centre: np.ndarray, rim_radius: float, z_min: float
) -> np.ndarray:
    """The ``lip_control="target"`` action naming a lip goal (m): :func:`lip_goal`'s inverse.

    Not clipped: a goal beyond the action's reach gives values outside [-1, 1].
    """
    g = np.asarray(goal, dtype=np.float64)
    xy = (g[:2] - np.asarray(rim_centre, dtype=np.float64)[:2]) / (LIP_REACH * rim_radius)
    return np.array([xy[0], xy[1], 2.0 * (g[2] - z_min) / LIP_RISE - 1.0])
