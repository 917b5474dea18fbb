"""The main job behind ``make demo``: rebuild a thesis object from a simulated scan.

Writes, into the output folder: the scan (PLY), the reconstructed mesh (OBJ), a PNG of the
ground truth beside the reconstruction, and the JSON report.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from pour_gym.fileio import save_mesh, save_point_cloud
from pour_gym.modelgen import generate_model
from pour_gym.objects import build_object
from pour_gym.render import render_mesh, render_points


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
