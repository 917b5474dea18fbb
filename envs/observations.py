"""What an observation may be: the modes an environment's ``obs_mode`` takes.

A light module (no simulator imported), so that command lines can offer the modes.
"""

from __future__ import annotations

from pour_gym.errors import InputError

# Vectors: the warped high-level features, or raw state.
VECTOR_MODES = ("features", "state")
# What a head camera gives (pour_gym.sim.sensors): depth and colour images, a point cloud.
SENSOR_MODES = ("depth", "rgb", "points")
OBS_MODES = VECTOR_MODES + SENSOR_MODES


def vector_mode(modes: tuple[str, ...]) -> str | None:
    """The vector mode among parsed modes (``"features"`` or ``"state"``), or None."""
    return next((m for m in modes if m in VECTOR_MODES), None)


def parse_obs_mode(obs_mode) -> tuple[str, ...]:
    """The modes of an ``obs_mode``: one name, or a list or tuple of names (a ``Dict``).

    Raises:
        ValueError: an unknown or repeated mode, none at all, or both vector modes.
    """
    modes = (obs_mode,) if isinstance(obs_mode, str) else tuple(obs_mode)
    unknown = [m for m in modes if m not in OBS_MODES]
    if unknown or not modes:
        raise InputError(
            f"obs_mode must be one of {OBS_MODES} or a tuple of them, not {obs_mode!r}"
        )
    if len(set(modes)) != len(modes):
        raise InputError(f"obs_mode names a mode twice: {obs_mode!r}")
    if sum(m in VECTOR_MODES for m in modes) > 1:
        raise InputError(
            f"obs_mode takes one of {VECTOR_MODES} at a time (with any sensors), not {obs_mode!r}"
        )
    return modes
