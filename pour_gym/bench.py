"""Benchmarks: ``pour-gym bench ...``. Timings are medians of repeated runs in one session.

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

from pour_gym.objects import build_object, cylinder_cup
from pour_gym.scan import ScanConfig, turntable_scan

_RUNNER = """
import json, resource, sys, time
import numpy as np
from pour_gym.reconstruct import reconstruct
from pour_gym.scan import PointCloud
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
    """Time and peak memory of :func:`pour_gym.reconstruct.reconstruct` per cloud size.

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
    lines = [
        "| points | seconds (median) | peak memory MB | of which imports MB |",
        "|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['n_points']} | {r['seconds']:.2f} | {r['peak_mb']:.0f} | {r['import_mb']:.0f} |"
        )
    return "\n".join(lines)


def _decimated(mesh, vertices: int):
    """The mesh simplified (quadric decimation) to about ``vertices`` vertices."""
    import trimesh

    from pour_gym.open3d_loader import open3d

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
    lines = [
        "| target vertices | label transfer s (median) | whole asset s (median) |",
        "|---:|---:|---:|",
    ]
    lines += [f"| {r['vertices']} | {r['transfer_s']:.2f} | {r['asset_s']:.2f} |" for r in rows]
    return "\n".join(lines)


def _tilting_cup(n: int, spacing: float):
    """A cylinder cup that holds ``n`` particles as a 6 cm column, and that column."""
    column = 0.06
    radius = float(np.sqrt(n * spacing**3 / (np.pi * column))) + spacing
    mesh = cylinder_cup(radius - 0.004, column + 0.04)
    g = np.arange(-radius + spacing / 2, radius, spacing)
    zs = np.arange(0.006 + spacing / 2, 0.2, spacing)
    pts = np.stack(np.meshgrid(g, g, zs, indexing="ij"), -1).reshape(-1, 3)
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) < radius - spacing / 2][:n]
    return mesh, pts


def bench_fluid(
    sizes: list[int],
    bullet_sizes: list[int] | tuple[int, ...] = (300, 2000),
    repeats: int = 3,
    seconds: float = 0.25,
) -> dict:
    """Particle-substeps per second of both fluid backends, side by side, in one run.

    Each case is a cylinder cup just wide enough to hold the particles as a 6 cm column,
    rocking +-15 degrees at 0.5 Hz (nothing spills). The fluid settles for 0.25 s, then
    ``repeats`` runs of ``seconds`` of simulated time are timed; the median is reported.
    PBF runs 4 solver iterations at 240 Hz substeps (more when particles move fast); the
    sphere backend steps pybullet at 240 Hz with the contact breaking threshold tuned to a
    fifth of the sphere radius (a bullet step counts as a substep).

    Args:
        sizes: particle counts for the position-based fluid.
        bullet_sizes: particle counts for the sphere backend.
        repeats: timed runs per case.
        seconds: simulated time per run, s.

    Returns:
        ``{"pbf": {"<n>": rate}, "bullet": {"<n>": rate}, "ratio_at_2000": x,
        "realtime": {"pbf": {...}, "bullet": {...}}, "rows": [...]}``.
    """
    import time

    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    from scipy.spatial.transform import Rotation

    from pour_gym.cache import cache_dir
    from pour_gym.fluid import PBFConfig, PBFluid, build_sdf
    from pour_gym.fluid.bullet import BulletFluid, convex_parts
    from pour_gym.sim.world import mesh_body, quiet_c_stdout

    cfg = PBFConfig()
    cases = [("pbf", n) for n in sizes] + [("bullet", n) for n in bullet_sizes]
    rates: dict = {"pbf": {}, "bullet": {}}
    realtime: dict = {"pbf": {}, "bullet": {}}
    rows = []
    bar = tqdm(total=len(cases) * repeats, desc="bench fluid", file=sys.stderr)
    for kind, n in cases:
        mesh, pts = _tilting_cup(n, cfg.spacing)
        client = None
        if kind == "pbf":
            fluid = PBFluid(pts, cfg)
            cup = fluid.add_collider(build_sdf(mesh, spacing=0.001))
        else:
            with quiet_c_stdout():
                client = BulletClient(connection_mode=pybullet.DIRECT)
            client.createMultiBody(0.0, client.createCollisionShape(pybullet.GEOM_PLANE))
            convex = convex_parts(client, mesh, cache_dir("sdf"))
            body = mesh_body(client, mesh, np.zeros(3), np.eye(3), (1.0, 1.0, 1.0, 1.0), convex)
            fluid = BulletFluid(client, pts, cfg)
            cup = fluid.add_collider(body)
        clock = [0.0]

        def step(fluid=fluid, cup=cup, clock=clock) -> int:
            clock[0] += 1 / 60
            angle = 15.0 * np.sin(np.pi * clock[0])
            cup.rotation = Rotation.from_euler("x", angle, degrees=True).as_matrix()
            return fluid.step(1 / 60)

        for _ in range(15):
            step()
        runs = []
        for _ in range(repeats):
            t = time.perf_counter()
            substeps = sum(step() for _ in range(round(seconds * 60)))
            wall = time.perf_counter() - t
            runs.append((n * substeps / wall, seconds / wall))
            bar.update()
        if client is not None:
            client.disconnect()
        rates[kind][str(n)] = statistics.median(r[0] for r in runs)
        realtime[kind][str(n)] = statistics.median(r[1] for r in runs)
        rows.append(
            {
                "backend": kind,
                "particles": n,
                "rate": rates[kind][str(n)],
                "realtime": realtime[kind][str(n)],
            }
        )
    bar.close()
    ratio = None
    if "2000" in rates["pbf"] and "2000" in rates["bullet"]:
        ratio = rates["pbf"]["2000"] / rates["bullet"]["2000"]
    return {
        "pbf": rates["pbf"],
        "bullet": rates["bullet"],
        "ratio_at_2000": ratio,
        "realtime": realtime,
        "rows": rows,
    }


def fluid_table(result: dict) -> str:
    """Markdown table of :func:`bench_fluid`."""
    lines = [
        "| backend | particles | particle-substeps/s (median) | simulated s per wall s |",
        "|---|---:|---:|---:|",
    ]
    lines += [
        f"| {r['backend']} | {r['particles']} | {r['rate']:.3g} | {r['realtime']:.2f} |"
        for r in result["rows"]
    ]
    if result.get("ratio_at_2000"):
        lines.append(f"\npbf / bullet at 2000 particles: {result['ratio_at_2000']:.1f}x")
    return "\n".join(lines)


def _env_rate(make, vector: str | None, steps: int, seed: int = 0) -> float:
    """Environment steps per second (all sub-environments together) over ``steps`` steps."""
    import time

    import gymnasium as gym

    if vector is None:
        env = make()
    elif vector == "sync":
        env = gym.vector.SyncVectorEnv([make, make])
    else:
        import os

        # Spawned workers (numba's OpenMP threads do not survive fork()), each with its
        # share of the cores: two workers of two threads on two cores fight for them.
        threads = os.environ.get("NUMBA_NUM_THREADS")
        os.environ["NUMBA_NUM_THREADS"] = str(max(1, (os.cpu_count() or 2) // 2))
        try:
            env = gym.vector.AsyncVectorEnv([make, make], context="spawn")
        finally:
            if threads is None:
                os.environ.pop("NUMBA_NUM_THREADS")
            else:
                os.environ["NUMBA_NUM_THREADS"] = threads
    n = 1 if vector is None else 2
    env.reset(seed=seed)
    env.action_space.seed(seed)
    env.step(env.action_space.sample())  # warm-up: assets, fields and kernels loaded
    t = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if vector is None and (terminated or truncated):
            env.reset()
    rate = steps * n / (time.perf_counter() - t)
    env.close()
    return rate


def bench_envs(steps: dict[str, int] | None = None, repeats: int = 3) -> dict:
    """Steps per second of every environment at its defaults, alone and vectorised by 2.

    Random actions; one-step environments count an episode per step. Pour-v0 also reports
    simulated seconds per wall second (a step is 0.1 s).

    Args:
        steps: steps per timed run by environment id (defaults: 100 for Pour-v0, 60 for
            the one-step environments).
        repeats: timed runs per case; the median is reported.

    Returns:
        ``{"rows": [{"env", "mode", "steps_per_s", "realtime"}...]}``.
    """
    import functools

    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments
    from pour_gym.envs import ENV_IDS

    steps = steps or {}
    rows = []
    bar = tqdm(total=len(ENV_IDS) * 3 * repeats, desc="bench envs", file=sys.stderr)
    for env_id in ENV_IDS:
        n = steps.get(env_id, 100 if env_id == "PourGym/Pour-v0" else 60)
        make = functools.partial(gym.make, env_id)
        for mode in (None, "sync", "async"):
            runs = []
            for r in range(repeats):
                runs.append(_env_rate(make, mode, n, seed=r))
                bar.update()
            rate = statistics.median(runs)
            dt = gym.make(env_id).unwrapped.dt
            rows.append(
                {
                    "env": env_id,
                    "mode": mode or "single",
                    "steps_per_s": rate,
                    "realtime": rate * dt if env_id == "PourGym/Pour-v0" else None,
                }
            )
    bar.close()
    return {"rows": rows}


def envs_table(result: dict) -> str:
    """Markdown table of :func:`bench_envs`."""
    lines = [
        "| environment | mode | steps/s (median) | simulated s per wall s |",
        "|---|---|---:|---:|",
    ]
    for r in result["rows"]:
        rt = "" if r["realtime"] is None else f"{r['realtime']:.2f}"
        lines.append(f"| {r['env']} | {r['mode']} | {r['steps_per_s']:.1f} | {rt} |")
    return "\n".join(lines)
