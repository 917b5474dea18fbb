"""Benchmark of the fluids: the position-based fluid against tuned pybullet spheres."""

from __future__ import annotations

import statistics
import sys

import numpy as np
from tqdm import tqdm

from pour_gym.objects import cylinder_cup
from pour_gym.report.tables import markdown_table


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

    The position-based fluid runs on this process's threads (:func:`default_threads`) and,
    when that is more than one, on one thread too: how a worker of a vector env runs it.
    Each case is a cylinder cup just wide enough to hold the particles as a 6 cm column,
    rocking +-15 degrees at 0.5 Hz (nothing spills). Every case's fluid settles for 0.25 s,
    then ``repeats`` rounds each time one run of ``seconds`` of simulated time per case, the
    cases in turn; the median per case is reported, and the ratio at 2000 particles is the
    median of the ratios within each round.
    PBF runs 4 solver iterations at 240 Hz substeps (more when particles move fast); the
    sphere backend steps pybullet at 240 Hz with the contact breaking threshold tuned to a
    fifth of the sphere radius (a bullet step counts as a substep).

    Args:
        sizes: particle counts for the position-based fluid.
        bullet_sizes: particle counts for the sphere backend.
        repeats: timed runs per case.
        seconds: simulated time per run, s.

    Returns:
        ``{"pbf": {"<n>": rate}, "pbf_one_thread": {"<n>": rate}, "bullet": {"<n>": rate},
        "threads": t, "ratio_at_2000": x, "ratios_at_2000": [per round], "realtime": {...},
        "rows": [...]}`` (rates in particle-substeps per second; ``pbf_one_thread`` empty
        when ``t`` is 1).
    """
    import time

    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    from scipy.spatial.transform import Rotation

    from pour_gym.fluid import PBFConfig, PBFluid, build_sdf, default_threads
    from pour_gym.fluid.bullet import BulletFluid, convex_parts
    from pour_gym.io.cache import cache_dir
    from pour_gym.io.stdio import redirect_stdout_fd
    from pour_gym.sim.world import mesh_body

    cfg = PBFConfig()
    threads = default_threads()
    kinds = ["pbf", "pbf_one_thread"] if threads > 1 else ["pbf"]
    cases = [(kind, n) for n in sizes for kind in kinds] + [("bullet", n) for n in bullet_sizes]
    rates: dict = {"pbf": {}, "pbf_one_thread": {}, "bullet": {}}
    realtime: dict = {"pbf": {}, "pbf_one_thread": {}, "bullet": {}}
    rows = []
    bar = tqdm(total=len(cases) * (repeats + 1), desc="bench fluid", file=sys.stderr)
    steppers = {}
    clients = []
    for kind, n in cases:
        mesh, pts = _tilting_cup(n, cfg.spacing)
        if kind != "bullet":
            fluid = PBFluid(pts, cfg, num_threads=1 if kind == "pbf_one_thread" else threads)
            fluid.wait_for_kernel()  # a build still compiling in a helper is not timed
            cup = fluid.add_collider(build_sdf(mesh, spacing=0.001))
        else:
            with redirect_stdout_fd():
                client = BulletClient(connection_mode=pybullet.DIRECT)
            clients.append(client)
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
        steppers[kind, n] = step
        bar.update()
    # The cases alternate run by run: this machine's speed drifts by 2x over minutes, and
    # a ratio between cases is fair only between runs taken side by side.
    runs: dict = {case: [] for case in cases}
    for _ in range(repeats):
        for (kind, n), step in steppers.items():
            t = time.perf_counter()
            substeps = sum(step() for _ in range(round(seconds * 60)))
            wall = time.perf_counter() - t
            runs[kind, n].append((n * substeps / wall, seconds / wall))
            bar.update()
    for client in clients:
        client.disconnect()
    for kind, n in cases:
        rates[kind][str(n)] = statistics.median(r[0] for r in runs[kind, n])
        realtime[kind][str(n)] = statistics.median(r[1] for r in runs[kind, n])
        rows.append(
            {
                "backend": kind,
                "threads": 1 if kind != "pbf" else threads,
                "particles": n,
                "rate": rates[kind][str(n)],
                "realtime": realtime[kind][str(n)],
            }
        )
    bar.close()
    ratio, each = None, []
    if ("pbf", 2000) in runs and ("bullet", 2000) in runs:
        # Within each round of runs, then the median over the rounds.
        each = [a[0] / b[0] for a, b in zip(runs["pbf", 2000], runs["bullet", 2000], strict=True)]
        ratio = statistics.median(each)
    return {
        "pbf": rates["pbf"],
        "pbf_one_thread": rates["pbf_one_thread"],
        "bullet": rates["bullet"],
        "threads": threads,
        "ratio_at_2000": ratio,
        "ratios_at_2000": each,
        "realtime": realtime,
        "rows": rows,
    }


def fluid_table(result: dict) -> str:
    """Markdown table of :func:`bench_fluid`."""
    header = [
        "backend", "threads", "particles", "particle-substeps/s (median)", "simulated s per wall s"
    ]  # fmt: skip
    names = {"pbf": "pbf", "pbf_one_thread": "pbf", "bullet": "bullet spheres"}
    cells = [
        [names[r["backend"]], r["threads"], r["particles"], f"{r['rate']:.3g}",
         f"{r['realtime']:.2f}"]
        for r in result["rows"]
    ]  # fmt: skip
    lines = [markdown_table(header, cells)]
    if result.get("ratio_at_2000"):
        each = ", ".join(f"{x:.1f}x" for x in result["ratios_at_2000"])
        lines.append(
            f"\npbf / bullet at 2000 particles: {result['ratio_at_2000']:.1f}x "
            f"(median of the ratios within each round of runs: {each})"
        )
    return "\n".join(lines)
