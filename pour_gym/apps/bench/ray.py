"""Benchmark of Ray: experiment and policy search here and on 1 and 2 Ray CPUs."""

from __future__ import annotations

import statistics
import sys

from tqdm import tqdm

from pour_gym.report.tables import markdown_table


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

    from pour_gym.agents.cluster import require_ray
    from pour_gym.agents.policies.search import search
    from pour_gym.agents.thesis.experiments import collect

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
    header = ["job", "here (s)", "Ray, 1 CPU (s)", "Ray, 2 CPUs (s)", "2 CPUs over 1",
              "2 CPUs over here"]  # fmt: skip
    rows = [
        [job, f"{row['serial']:.1f}", f"{row['ray_1cpu']:.1f}", f"{row['ray_2cpu']:.1f}",
         f"{result['speedup_2cpu_over_1cpu'][job]:.2f}x",
         f"{result['speedup_2cpu_over_serial'][job]:.2f}x"]
        for job, row in s.items()
    ]  # fmt: skip
    lines = [markdown_table(header, rows)]
    lines += ["", f"starting Ray: {result['ray_start_s']:.1f} s", ""]
    machines = next(iter(result["scaling"].values()))["rows"]
    header = ["full-size job", "s per episode", *(f"{r['machines']} machines" for r in machines)]
    names = {"experiment": "experiment tilt (3600 episodes)", "search": "search (6 x 6 x 3)"}
    rows = [
        [
            names[job],
            f"{sc['episode_s']:.2f}",
            *(f"{r['seconds'] / 60:.1f} min" for r in sc["rows"]),
        ]
        for job, sc in result["scaling"].items()
    ]
    lines.append(markdown_table(header, rows))
    return "\n".join(lines)
