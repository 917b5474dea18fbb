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
    from pour_gym.sim.world import mesh_body
    from pour_gym.stdio import redirect_stdout_fd

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
            with redirect_stdout_fd():
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
    """Environment steps per second (all sub-environments together) over ``steps`` steps.

    ``vector``: None (one env), ``"sync"`` / ``"async"`` (Gymnasium's vector envs of two,
    async with Gymnasium's default start method), ``"dummy"`` / ``"subproc_<n>"`` (SB3's).
    Random actions; episodes restart as they end (their resets are in the time).
    """
    import time

    import gymnasium as gym

    if vector is None:
        env, n = make(), 1
    elif vector in ("sync", "async"):
        cls = gym.vector.SyncVectorEnv if vector == "sync" else gym.vector.AsyncVectorEnv
        env, n = cls([make, make]), 2
    else:
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

        n = 1 if vector == "dummy" else int(vector.split("_")[1])
        env = DummyVecEnv([make]) if vector == "dummy" else SubprocVecEnv([make] * n)
    sb3 = vector is not None and vector not in ("sync", "async")
    space = env.action_space
    space.seed(seed)

    def act():
        return np.stack([space.sample() for _ in range(n)]) if sb3 else space.sample()

    if sb3:
        env.seed(seed)
        env.reset()
    else:
        env.reset(seed=seed)
    env.step(act())  # warm-up: assets, fields and kernels loaded
    t = time.perf_counter()
    for _ in range(steps):
        out = env.step(act())
        if vector is None and (out[2] or out[3]):
            env.reset()
    rate = steps * n / (time.perf_counter() - t)
    env.close()
    return rate


def _pour_realtime(
    kwargs: dict, episodes: int, seed: int = 0, env_id: str = "PourGym/Pour-v0"
) -> float:
    """Simulated s per wall s of the scripted policy's episode steps, red cup -> broad cup."""
    import time

    import gymnasium as gym

    from pour_gym.agents.scripted import ScriptedPourPolicy

    env = gym.make(env_id, source_objects="red_cup", target_objects="broad_cup", **kwargs)
    policy = ScriptedPourPolicy()
    steps, wall = 0, 0.0
    for k in range(episodes + 1):  # the first episode loads and compiles: not timed
        obs, _ = env.reset(seed=seed + k)
        policy.reset()
        done = False
        while not done:
            action = policy(obs)
            t = time.perf_counter()
            obs, _, terminated, truncated, _ = env.step(action)
            if k > 0:
                wall += time.perf_counter() - t
                steps += 1
            done = terminated or truncated
    env.close()
    return steps * env.unwrapped.dt / wall


def bench_envs(repeats: int = 3, steps: int = 600) -> dict:
    """Speed of the environments at their defaults, side by side in one run.

    - ``pour_v0``: the scripted policy pouring from the red cup into the broad cup, episode
      steps only: simulated seconds per wall second (``realtime``), steps per second, and
      the same with the fill of 1000 particles the first release used (``realtime_1000``).
    - ``panda_pour_v0``: the same episodes (same seeds, so the same fills) with the Panda
      holding the cup, each timed run right after Pour-v0's; its speed over Pour-v0's
      (``over_pour_v0``) is the median of the ratios of those pairs.
    - ``vec``: Pour-v0 env-steps per second under random actions, SB3's vector envs:
      ``dummy_1`` (one env in this process, default threads), ``one_thread`` (the same
      with ``num_threads=1``), ``subproc_2`` and ``subproc_4`` (worker processes); the
      first three alternate run by run, and ``ratios`` are medians of the ratios within
      each run's trio.
    - ``rows``: the one-step environments alone and vectorised by two (Gymnasium's).

    Args:
        repeats: timed runs per case; the median is reported.
        steps: steps per timed run of the vector cases (600: several episodes, so that
            resets and long steps average out as they do in training).
    """
    import functools

    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments

    cases = 3 + 4 + 2 * 3
    bar = tqdm(total=cases * repeats, desc="bench envs", file=sys.stderr)

    def median(fn) -> float:
        runs = []
        for r in range(repeats):
            runs.append(fn(r))
            bar.update()
        return float(statistics.median(runs))

    # Pour-v0 and PandaPour-v0 alternate, run by run: the ratio is taken within each pair
    # (this machine's speed drifts by 2x over minutes), and its median reported.
    pairs = []
    for r in range(repeats):
        alone = _pour_realtime({}, 2, seed=100 * r)
        bar.update()
        held = _pour_realtime({}, 2, seed=100 * r, env_id="PourGym/PandaPour-v0")
        bar.update()
        pairs.append((alone, held))
    realtime = float(statistics.median(a for a, _ in pairs))
    panda = float(statistics.median(b for _, b in pairs))
    panda_ratio = float(statistics.median(b / a for a, b in pairs))
    realtime_1000 = median(lambda r: _pour_realtime({"source_particles": 1000}, 2, seed=100 * r))
    pour = functools.partial(gym.make, "PourGym/Pour-v0")
    single = functools.partial(gym.make, "PourGym/Pour-v0", num_threads=1)
    # The cases a ratio is taken between alternate run by run, as above.
    runs: dict[str, list[float]] = {"dummy_1": [], "one_thread": [], "subproc_2": []}
    for r in range(repeats):
        for name, make, mode in (
            ("dummy_1", pour, "dummy"),
            ("one_thread", single, "dummy"),
            ("subproc_2", pour, "subproc_2"),
        ):
            runs[name].append(_env_rate(make, mode, steps, seed=r))
            bar.update()
    vec = {name: float(statistics.median(v)) for name, v in runs.items()}
    vec["subproc_4"] = median(lambda r: _env_rate(pour, "subproc_4", steps, seed=r))
    ratio_one = statistics.median(
        b / a for a, b in zip(runs["one_thread"], runs["subproc_2"], strict=True)
    )
    ratio_default = statistics.median(
        b / a for a, b in zip(runs["dummy_1"], runs["subproc_2"], strict=True)
    )
    rows = []
    for env_id in ("PourGym/ParticleDrop-v0", "PourGym/TiltPour-v0"):
        make = functools.partial(gym.make, env_id)
        for mode in (None, "sync", "async"):
            rate = median(lambda r, make=make, mode=mode: _env_rate(make, mode, 60, seed=r))
            rows.append({"env": env_id, "mode": mode or "single", "steps_per_s": rate})
    bar.close()
    return {
        "pour_v0": {
            "realtime": realtime,
            "steps_per_s": realtime / 0.1,
            "realtime_1000": realtime_1000,
        },
        "panda_pour_v0": {
            "realtime": panda,
            "steps_per_s": panda / 0.1,
            "over_pour_v0": panda_ratio,
        },
        "vec": vec,
        "ratios": {
            "subproc_2_over_one_thread": float(ratio_one),
            "subproc_2_over_default": float(ratio_default),
        },
        "rows": rows,
    }


def envs_table(result: dict) -> str:
    """Markdown tables of :func:`bench_envs`."""
    p, v, q = result["pour_v0"], result["vec"], result["ratios"]
    a = result["panda_pour_v0"]
    lines = [
        "| Pour-v0, scripted policy, red cup -> broad cup | simulated s per wall s |",
        "|---|---:|",
        f"| defaults (fill T + 100) | {p['realtime']:.2f} |",
        f"| 1000 particles | {p['realtime_1000']:.2f} |",
        f"| PandaPour-v0, the Panda holding the cup (defaults, the same episodes) | "
        f"{a['realtime']:.2f} ({a['over_pour_v0']:.2f}x Pour-v0) |",
        "",
        "| Pour-v0, random actions, SB3 vector env | env-steps/s |",
        "|---|---:|",
        f"| DummyVecEnv, 1 env, default threads | {v['dummy_1']:.1f} |",
        f"| DummyVecEnv, 1 env, num_threads=1 | {v['one_thread']:.1f} |",
        f"| SubprocVecEnv, 2 workers | {v['subproc_2']:.1f} |",
        f"| SubprocVecEnv, 4 workers | {v['subproc_4']:.1f} |",
        "",
        f"SubprocVecEnv(2) over one env on one thread: {q['subproc_2_over_one_thread']:.2f}x; "
        f"over one env at its default threads: {q['subproc_2_over_default']:.2f}x",
        "",
        "| environment | mode | steps/s (median) |",
        "|---|---|---:|",
    ]
    for r in result["rows"]:
        lines.append(f"| {r['env']} | {r['mode']} | {r['steps_per_s']:.1f} |")
    return "\n".join(lines)


def bench_ray(repeats: int = 3, machines: tuple[int, ...] = (1, 2, 4, 8)) -> dict:
    """Experiment and policy search here, and on Ray with 1 and 2 CPUs, side by side.

    The jobs: experiment 2 (``tilt``) on two containers, 20 episodes each in tasks of 5 (8
    tasks); one policy-search generation of 4 candidates with 2 episodes each (4 tasks
    after the starting parameters' one). Each case is timed with its Ray instance up;
    starting Ray is timed apart (``ray_start_s``).

    ``scaling`` is a calculation, not a measurement: from the seconds per episode on one
    Ray CPU (``episode_s``, Ray's overhead included), a job of independent tasks on N
    machines of 2 CPUs takes as many rounds of tasks as N * 2 CPUs need. It is given for
    the full jobs: the tilt experiment at its defaults (9 containers x 400 episodes in
    tasks of 20: 180 tasks) and a search at its defaults (6 generations of 6 candidates
    of 3 episodes; only a generation's candidates run side by side).

    Args:
        repeats: timed runs per case; the median is reported.
        machines: machine counts of the scaling calculation (2 CPUs each, as this one).
    """
    import math
    import time

    from pour_gym.agents.experiments import collect
    from pour_gym.agents.search import search
    from pour_gym.cluster import require_ray

    ray = require_ray()
    jobs = {  # name: (run, episodes in the job)
        "experiment": (
            lambda address: collect("tilt", ("red_cup", "standard_bowl"), 20, 0, address, 5),
            40,
        ),
        "search": (
            lambda address: search(
                "red_cup", 1, 4, 2, seed=0, env_kwargs={"amount_range": (100, 150)},
                address=address,
            ),
            10,
        ),
    }  # fmt: skip
    cases = {"serial": None, "ray_1cpu": 1, "ray_2cpu": 2}
    bar = tqdm(total=len(jobs) * len(cases) * repeats, desc="bench ray", file=sys.stderr)
    seconds: dict[str, dict[str, float]] = {job: {} for job in jobs}
    starts = []
    for case, cpus in cases.items():
        if cpus is not None:
            t = time.perf_counter()
            ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False)
            starts.append(time.perf_counter() - t)
        for job, (run, _) in jobs.items():
            runs = []
            for _ in range(repeats):
                t = time.perf_counter()
                run(None if cpus is None else "local")
                runs.append(time.perf_counter() - t)
                bar.update()
            seconds[job][case] = float(statistics.median(runs))
        if cpus is not None:
            ray.shutdown()
    bar.close()
    scaling = {}
    for job, (_, episodes) in jobs.items():
        episode_s = seconds[job]["ray_1cpu"] / episodes
        rows = []
        for m in machines:
            cpus = 2 * m
            if job == "experiment":  # 180 tasks of 20 episodes
                total = math.ceil(180 / cpus) * 20 * episode_s
            else:  # 6 generations, each 6 candidates of 3 episodes side by side
                total = 6 * math.ceil(6 / cpus) * 3 * episode_s
            rows.append({"machines": m, "cpus": cpus, "seconds": total})
        scaling[job] = {"episode_s": episode_s, "rows": rows}
    return {
        "seconds": seconds,
        "speedup_2cpu_over_1cpu": {j: s["ray_1cpu"] / s["ray_2cpu"] for j, s in seconds.items()},
        "speedup_2cpu_over_serial": {j: s["serial"] / s["ray_2cpu"] for j, s in seconds.items()},
        "ray_start_s": float(statistics.median(starts)),
        "scaling": scaling,
    }


def ray_table(result: dict) -> str:
    """Markdown tables of :func:`bench_ray`."""
    s = result["seconds"]
    lines = [
        "| job | here (s) | Ray, 1 CPU (s) | Ray, 2 CPUs (s) | 2 CPUs over 1 | 2 CPUs over here |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for job, row in s.items():
        lines.append(
            f"| {job} | {row['serial']:.1f} | {row['ray_1cpu']:.1f} | {row['ray_2cpu']:.1f} | "
            f"{result['speedup_2cpu_over_1cpu'][job]:.2f}x | "
            f"{result['speedup_2cpu_over_serial'][job]:.2f}x |"
        )
    lines += ["", f"starting Ray: {result['ray_start_s']:.1f} s", ""]
    lines += ["| full-size job | s per episode | " + " | ".join(
        f"{r['machines']} machines" for r in next(iter(result["scaling"].values()))["rows"]
    ) + " |"]  # fmt: skip
    lines.append("|---|---:|" + "---:|" * len(next(iter(result["scaling"].values()))["rows"]))
    names = {"experiment": "experiment tilt (3600 episodes)", "search": "search (6 x 6 x 3)"}
    for job, sc in result["scaling"].items():
        cells = " | ".join(f"{r['seconds'] / 60:.1f} min" for r in sc["rows"])
        lines.append(f"| {names[job]} | {sc['episode_s']:.2f} | {cells} |")
    return "\n".join(lines)
