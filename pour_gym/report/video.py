"""Writing rollouts as animated GIF (always available) or MP4 (with imageio-ffmpeg)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pour_gym.errors import InputError

FORMATS = (".gif", ".mp4")


def write_video(frames: Sequence[np.ndarray], path: str | Path, fps: float = 20.0) -> Path:
    """Write RGB frames to a GIF or MP4 file.

    Args:
        frames: (H, W, 3) uint8 images, all the same size.
        path: output file; its suffix picks the format (``.gif`` or ``.mp4``).
        fps: frames per second.

    Returns:
        The path written.

    Raises:
        InputError: no frames, an unknown suffix, or MP4 without imageio-ffmpeg.
    """
    import imageio.v3 as iio

    path = Path(path)
    if not frames:
        raise InputError("no frames to write")
    if path.suffix.lower() not in FORMATS:
        raise InputError(f"write a video as {' or '.join(FORMATS)}, not {path.suffix!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    stack = np.stack([np.asarray(f, dtype=np.uint8) for f in frames])
    if path.suffix.lower() == ".gif":
        iio.imwrite(path, stack, duration=1000.0 / fps, loop=0)
        return path
    try:
        import imageio_ffmpeg  # noqa: F401 - only its presence is checked
    except ImportError:
        raise InputError(
            "MP4 needs the imageio-ffmpeg package (pip install imageio-ffmpeg); or write a .gif"
        ) from None
    iio.imwrite(path, stack, fps=fps, codec="libx264", macro_block_size=8)
    return path
