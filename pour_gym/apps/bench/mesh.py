"""Benchmarks of chapter 3 and 4: reconstruction (time, peak memory) and labelling.

Reconstruction runs each repeat in a fresh Python process, so that the peak resident
memory it reports (``ru_maxrss``) belongs to that run alone.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pour_gym.mesh.scan import ScanConfig, turntable_scan
from pour_gym.objects import build_object
from pour_gym.report.tables import markdown_table

_RUNNER = """
import json, resource, sys, time
import numpy as np
from pour_gym.mesh.reconstruct import reconstruct
from pour_gym.mesh.scan import PointCloud
data = np.load(sys.argv[1])
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.perf_counter()
rec = reconstruct(PointCloud(points=data[:, :3], normals=data[:, 3:]))
seconds = time.perf_counter() - t
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"seconds": seconds, "peak_mb": peak / 1024, "import_mb": base / 1024,
                  "stages": rec.seconds, "watertight": bool(rec.mesh.is_watertight)}))
"""


def _dense_scan() -> np.ndarray:
    """A dense scan of the red cup (about 400k points with normals)."""
    cup = build_object("red_cup")
    cfg = ScanConfig(views=48, width=400, height=300, elevations_deg=(5.0, 20.0, 35.0))
    cloud = turntable_scan(cup.mesh, cup.labels, cfg)
    return np.hstack([cloud.points, cloud.normals])


def bench_reconstruct(sizes: list[int], repeats: int = 3, seed: int = 0) -> list[dict]:
    """Time and peak memory of :func:`pour_gym.mesh.reconstruct.reconstruct` per cloud size.

    Args:
        sizes: numbers of points, drawn without replacement from a dense scan of the red cup.
        repeats: runs per size; the table holds medians.
        seed: seed of the subsampling.

    Returns:
        One row per size: ``n_points``, ``seconds`` and ``peak_mb`` (medians), ``runs``.
    """
    dense = _dense_scan()
    if max(sizes) > len(dense):
        raise ValueError(f"the dense scan has {len(dense)} points; largest size is {max(sizes)}")
    rng = np.random.default_rng(seed)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        warm = Path(tmp) / "warm.npy"
        np.save(warm, dense[rng.choice(len(dense), 2000, replace=False)])
        # The first run compiles the numba kernels into the cache; it is not timed.
        subprocess.run([sys.executable, "-c", _RUNNER, str(warm)], check=True, capture_output=True)
        bar = tqdm(total=len(sizes) * repeats, desc="bench reconstruct", file=sys.stderr)
        for n in sizes:
            path = Path(tmp) / f"cloud_{n}.npy"
            np.save(path, dense[rng.choice(len(dense), n, replace=False)])
            runs = []
            for _ in range(repeats):
                out = subprocess.run(
                    [sys.executable, "-c", _RUNNER, str(path)],
                    check=True,
                    capture_output=True,
                    text=True,
                )
                runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
                bar.update()
            rows.append(
                {
                    "n_points": n,
                    "seconds": statistics.median(r["seconds"] for r in runs),
                    "peak_mb": statistics.median(r["peak_mb"] for r in runs),
                    "import_mb": statistics.median(r["import_mb"] for r in runs),
                    "runs": runs,
                }
            )
        bar.close()
    return rows


def reconstruct_table(rows: list[dict]) -> str:
    """Markdown table of :func:`bench_reconstruct` rows."""
    header = ["points", "seconds (median)", "peak memory MB", "of which imports MB"]
    cells = [
        [r["n_points"], f"{r['seconds']:.2f}", f"{r['peak_mb']:.0f}", f"{r['import_mb']:.0f}"]
        for r in rows
    ]
    return markdown_table(header, cells, align="rrrr")


def _decimated(mesh, vertices: int):
    """The mesh simplified (quadric decimation) to about ``vertices`` vertices."""
    import trimesh

    from pour_gym.io.open3d_loader import open3d

    o3d = open3d()
    m = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(mesh.vertices)),
        o3d.utility.Vector3iVector(np.asarray(mesh.faces)),
    )
    m = m.simplify_quadric_decimation(target_number_of_triangles=2 * vertices)
    return trimesh.Trimesh(np.asarray(m.vertices), np.asarray(m.triangles), process=True)


def bench_label(sizes: list[int], repeats: int = 3) -> list[dict]:
    """Time of labelling a target of each vertex count (broad cup, remeshed, any pose).

    Two figures per size: the label transfer alone (frame search, correspondences,
    smoothing) and the whole asset (transfer plus container geometry and cavity).

    Args:
        sizes: target vertex counts.
        repeats: runs per size; medians are reported.

    Returns:
        One row per size: ``vertices``, ``transfer_s``, ``asset_s``.
    """
    import time

    import trimesh
    from scipy.spatial.transform import Rotation

    from pour_gym.assets import label_container
    from pour_gym.warp.transfer import transfer_best

    source = build_object("red_cup")
    dense = build_object("broad_cup").mesh
    v, f = trimesh.remesh.subdivide(dense.vertices, dense.faces)
    dense = trimesh.Trimesh(v, f, process=True)
    rows = []
    bar = tqdm(total=len(sizes) * repeats, desc="bench label", file=sys.stderr)
    label_container(source.mesh.copy())  # warm-up: imports and caches
    for n in sizes:
        target = _decimated(dense, n)
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_euler("xyz", [40, 10, 70], degrees=True).as_matrix()
        target.apply_transform(pose)
        transfer, whole = [], []
        for _ in range(repeats):
            t = time.perf_counter()
            transfer_best(source.mesh, source.labels, target)
            transfer.append(time.perf_counter() - t)
            t = time.perf_counter()
            label_container(target)
            whole.append(time.perf_counter() - t)
            bar.update()
        rows.append(
            {
                "vertices": len(target.vertices),
                "transfer_s": statistics.median(transfer),
                "asset_s": statistics.median(whole),
            }
        )
    bar.close()
    return rows


def label_table(rows: list[dict]) -> str:
    """Markdown table of :func:`bench_label` rows."""
    header = ["target vertices", "label transfer s (median)", "whole asset s (median)"]
    cells = [[r["vertices"], f"{r['transfer_s']:.2f}", f"{r['asset_s']:.2f}"] for r in rows]
    return markdown_table(header, cells, align="rrr")
