"""Pictures of what the sensor observation modes give (``pour-gym report sensors``).

One sheet per environment: the colour image, the depth image and the point cloud (by
segment) an agent receives at the env's defaults, at a moment where there is fluid to
see: Pour-v0 and PandaPour-v0 (the arm drawn) in the middle of the scripted policy's pour,
TiltPour-v0 tilted with its fill, ParticleDrop-v0 with its blob over the container.
"""

from __future__ import annotations

import sys
from pathlib import Path

from tqdm import tqdm

from pour_gym.report.pictures import save_figure
from pour_gym.sim.sensors import SEGMENTS

MODES = ("rgb", "depth", "points")
SEGMENT_COLORS = {1: "#d43333", 2: "#9a9a90", 3: "#3373e6", 4: "#a89070", 5: "#55555f"}


def observe_scene(env_id: str, seed: int = 0) -> tuple[dict, str]:
    """The three sensor observations at a moment worth a picture, and what it shows.

    Returns:
        ``({mode: observation}, caption)``.
    """
    import gymnasium as gym

    import pour_gym  # noqa: F401  (registers the envs)
    from pour_gym.agents.policies.scripted import ScriptedPourPolicy, action_settings

    env = gym.make(env_id, objects="red_cup", obs_mode=("features", *MODES))
    if "Tilt" in env_id:
        obs, _ = env.reset(seed=seed, options={"tilt_deg": 70.0, "fill": 0.6})
        caption = "the red cup filled to 60 % and tilted to 70 degrees"
    elif "Drop" in env_id:
        obs, _ = env.reset(seed=seed, options={"spawn": [0.02, 0.0, 0.12]})
        caption = "a blob of fluid over the red cup"
    else:
        obs, info = env.reset(
            seed=seed, options={"source": "red_cup", "target": "broad_cup", "target_amount": 200}
        )
        policy = ScriptedPourPolicy(amount=info["target_amount"], **action_settings(env_id))
        for _ in range(250):
            obs, _, terminated, truncated, info = env.step(policy(obs["features"]))
            if info["poured"] >= 0.4 * info["target_amount"] or terminated or truncated:
                break
        caption = f"the scripted policy pouring, {info['poured']} of {info['target_amount']} poured"
    env.close()
    return {m: obs[m] for m in MODES}, caption


def sensor_sheet(env_id: str, path: str | Path, seed: int = 0) -> Path:
    """Write a PNG of an env's rgb, depth and points observations side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    obs, caption = observe_scene(env_id, seed)
    fig = plt.figure(figsize=(12, 4))
    ax = fig.add_subplot(1, 3, 1)
    ax.imshow(obs["rgb"], interpolation="nearest")
    ax.set_title(f'"rgb" {obs["rgb"].shape}', fontsize=10)
    ax.axis("off")
    ax = fig.add_subplot(1, 3, 2)
    ax.imshow(obs["depth"][..., 0], cmap="gray", interpolation="nearest", vmin=0, vmax=255)
    ax.set_title(f'"depth" {obs["depth"].shape} (near dark)', fontsize=10)
    ax.axis("off")
    cloud = obs["points"].reshape(-1, 4)
    ax = fig.add_subplot(1, 3, 3, projection="3d")
    for segment, colour in SEGMENT_COLORS.items():
        pts = cloud[cloud[:, 3] == segment]
        name = next(k for k, v in SEGMENTS.items() if v == segment)
        ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=2, c=colour, label=f"{name} ({len(pts)})")
    ax.view_init(elev=35, azim=-100)
    ax.set_title(f'"points" ({len(cloud)} x 4, world frame)', fontsize=10)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_axis_off()
    fig.suptitle(f"{env_id}: {caption}", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, path)


def sensor_sheets(env_ids: list[str], out: str | Path, seed: int = 0) -> list[Path]:
    """A sheet per environment in ``out`` (``<env name>.png``)."""
    out = Path(out)
    return [
        sensor_sheet(env_id, out / f"{env_id.split('/')[-1].lower()}.png", seed)
        for env_id in tqdm(env_ids, desc="sensor pictures", file=sys.stderr)
    ]
