"""The main job behind ``make demo``: from a scan to a pour.

Writes, into the output folder: the scan (PLY), the reconstructed mesh (OBJ), a PNG of the
ground truth beside the reconstruction, the JSON report, and a GIF of one PourGym/Pour-v0
episode in which the scripted features policy pours from the red cup into the broad cup.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from pour_gym.envs import POUR_V0, entry, make, task_of
from pour_gym.errors import InputError
from pour_gym.mesh.fileio import save_mesh, save_point_cloud
from pour_gym.mesh.modelgen import generate_model
from pour_gym.objects import build_object
from pour_gym.report.pictures import render_mesh, render_points


def _side_by_side(paths: list[Path], titles: list[str], out: Path) -> Path:
    fig, axes = plt.subplots(1, len(paths), figsize=(6 * len(paths), 5))
    for ax, p, t in zip(axes, paths, titles, strict=True):
        ax.imshow(plt.imread(p))
        ax.set_title(t)
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


def run_demo(out: Path, obj: str = "red_cup") -> dict:
    """Scan, reconstruct and measure one thesis object; write the results to ``out``.

    Args:
        out: output folder (created).
        obj: thesis object name.

    Returns:
        A summary with the written paths, the report and a ``text`` for the terminal.
    """
    out.mkdir(parents=True, exist_ok=True)
    truth = build_object(obj)
    result = generate_model(obj)
    scan_path = save_point_cloud(result.cloud, out / f"{obj}_scan.ply")
    mesh_path = save_mesh(result.reconstruction.mesh, out / f"{obj}.obj")
    report_path = out / f"{obj}.json"
    report_path.write_text(json.dumps(result.report, indent=2))
    views = ((25.0, -60.0),)
    parts = [
        render_mesh(truth.mesh, out / "_truth.png", labels=truth.labels, views=views),
        render_points(result.cloud.points, out / "_scan.png"),
        render_mesh(result.reconstruction.mesh, out / "_rec.png", views=views),
    ]
    png = _side_by_side(
        parts,
        [
            "ground truth (labelled)",
            f"turntable scan, {len(result.cloud.points)} points",
            "reconstruction (offset inner model)",
        ],
        out / f"{obj}.png",
    )
    for p in parts:
        p.unlink()
    m = result.report["models"][result.chosen]
    err = m["errors"]
    text = (
        f"{obj}: scanned {result.report['n_points']} points, reconstructed in "
        f"{result.report['seconds']:.1f} s\n"
        f"  height {m['height'] * 100:.2f} cm (error {err['height']['rel_error']:.1%}), "
        f"rim radius {m['rim_radius'] * 100:.2f} cm ({err['rim_radius']['rel_error']:.1%}), "
        f"volume {m['volume'] * 1e6:.0f} ml ({err['volume']['rel_error']:.1%})\n"
        f"  wrote {scan_path}, {mesh_path}, {png}, {report_path}"
    )
    return {
        "scan": str(scan_path),
        "mesh": str(mesh_path),
        "png": str(png),
        "report": result.report,
        "text": text,
    }


def episode_gif(
    out: Path,
    env_id: str = POUR_V0,
    source: str = "red_cup",
    target: str = "broad_cup",
    seed: int = 0,
    target_amount: int | None = None,
    episodes: int = 8,
    liquid: str | None = None,
) -> dict:
    """Record an environment at work as a GIF named by its id (``pour-v0.gif``, ...).

    A pouring task: one episode of the scripted policy from ``source`` into ``target``.
    A one-step task: ``episodes`` episodes with random actions on ``source``, a frame
    before and after each step.

    Args:
        out: output folder (created).
        env_id: a registered id.
        source: the (held) container.
        target: the container on the table (pouring tasks).
        seed: the (first) episode's seed.
        target_amount: particles to pour (random in the environment's range if None).
        episodes: episodes of a one-step task.
        liquid: a liquid's preset (:mod:`pour_gym.fluid.liquid`; the GIF is then
            ``<id>-<liquid>.gif``), or None for the env's water.

    Returns:
        The last step's info, the video path and a ``text`` for the terminal.

    Raises:
        InputError: an id that is not pour-gym's.
    """
    from tqdm import tqdm

    from pour_gym.agents.policies.rollout import rollout
    from pour_gym.agents.policies.scripted import ScriptedPourPolicy, action_settings
    from pour_gym.report.video import write_video

    try:
        task, slug = task_of(env_id), entry(env_id).slug
    except ValueError as exc:
        raise InputError(str(exc)) from None
    out.mkdir(parents=True, exist_ok=True)
    name = env_id.split("/")[-1]
    more = {} if liquid is None else {"liquid": liquid}
    if task.pours:
        env = make(env_id, render_mode="rgb_array", **more)
        options = {"source": source, "target": target}
        if target_amount is not None:
            options["target_amount"] = target_amount
        bar = tqdm(desc="episode", unit="step", file=sys.stderr)
        policy = ScriptedPourPolicy(**action_settings(env_id))
        episode = rollout(env, policy, seed=seed, options=options, frames=True,
                          on_step=lambda _: bar.update() and False)  # fmt: skip
        bar.close()
        env.close()
        frames, info = episode.frames, episode.info
        text = (
            f"{name}, scripted policy, {source} -> {target}"
            f"{'' if liquid is None else ', ' + liquid}: poured {info['poured']} "
            f"particles ({info['poured_ml']:.1f} ml) for a target of {info['target_amount']} "
            f"({info['target_ml']:.1f} ml, tolerance {info['tolerance']}), spilled "
            f"{info['spilled']}, {'success' if info['is_success'] else 'failure'}"
        )
    else:
        env = make(env_id, objects=[source], render_mode="rgb_array", **more)
        env.action_space.seed(seed)
        frames, right = [], 0
        for k in tqdm(range(episodes), desc="episodes", file=sys.stderr):
            episode = rollout(env, lambda _: env.action_space.sample(), seed=seed + k,
                              frames=True)  # fmt: skip
            frames += episode.frames
            right += int(episode.info["is_success"])
        env.close()
        info = episode.info
        text = f"{name}, random actions on {source}: {right} of {episodes} right"
    stem = slug if liquid is None else f"{slug}-{liquid}"
    video = write_video(frames, out / f"{stem}.gif", fps=10 if task.pours else 2)
    return {"info": info, "video": str(video), "text": f"{text}\n  wrote {video}"}
