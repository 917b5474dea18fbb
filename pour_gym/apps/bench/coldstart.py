"""Benchmark of a new process's start: from ``import pour_gym`` to the first step's return.

Each measurement is a new Python process that imports pour-gym, makes an environment,
resets it and steps it once with a random action, reporting the seconds of each part. It
runs three times per environment id, in this order:

- ``cold``: numba's cache empty (a fresh ``NUMBA_CACHE_DIR``), pour-gym's own cache of
  fields and cavities as it is: the first run of a new pour-gym version;
- ``new_machine``: both caches empty (a fresh ``POUR_GYM_CACHE`` too): a new user;
- ``warm``: both caches as the runs before left them: every later process.

Between runs the benchmark waits for the helper processes that compile the kernel
(:mod:`pour_gym.fluid.precompile`) to finish, so that no run shares the machine with the
one before.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from tqdm import tqdm

from pour_gym.report.tables import markdown_table

# The process each measurement runs (its clock starts before pour-gym's import).
_SCRIPT = """
import json, sys, time
start = time.perf_counter()
import gymnasium as gym
import pour_gym
imported = time.perf_counter()
env = gym.make(sys.argv[1])
made = time.perf_counter()
env.reset(seed=0)
reset = time.perf_counter()
env.action_space.seed(0)
env.step(env.action_space.sample())
stepped = time.perf_counter()
env.close()
print(json.dumps({"import": imported - start, "make": made - imported, "reset": reset - made,
                  "first_step": stepped - reset, "total": stepped - start}))
"""

RUNS = ("cold", "new_machine", "warm")


def _measure(env_id: str, environ: dict) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", _SCRIPT, env_id],
        env=environ,
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"the {env_id} start-up process failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def bench_coldstart(env_ids: list[str] | tuple[str, ...]) -> dict:
    """Seconds from import to the first step's return, per env id, cold and warm.

    Args:
        env_ids: environment ids.

    Returns:
        ``{"runs": [{"env": id, "run": "cold" | "new_machine" | "warm", "import": s,
        "make": s, "reset": s, "first_step": s, "total": s}, ...]}``.
    """
    from pour_gym.fluid.precompile import wait_for_helpers

    rows = []
    bar = tqdm(total=len(env_ids) * len(RUNS), desc="bench coldstart", file=sys.stderr)
    for env_id in env_ids:
        with tempfile.TemporaryDirectory(prefix="pour-gym-coldstart-") as tmp:
            first, fresh, assets = (str(Path(tmp) / name) for name in ("first", "fresh", "assets"))
            # (numba's cache, pour-gym's cache or None for the user's) per run
            caches = {
                "cold": (first, None),
                "new_machine": (fresh, assets),
                "warm": (fresh, assets),
            }
            for run in RUNS:
                numba_cache, pour_gym_cache = caches[run]
                environ = {**os.environ, "NUMBA_CACHE_DIR": numba_cache}
                if pour_gym_cache is not None:
                    environ["POUR_GYM_CACHE"] = pour_gym_cache
                rows.append({"env": env_id, "run": run, **_measure(env_id, environ)})
                wait_for_helpers(Path(numba_cache))
                bar.update()
    bar.close()
    return {"runs": rows}


def coldstart_table(result: dict) -> str:
    """Markdown table of :func:`bench_coldstart`."""
    header = ["env", "run", "import s", "make s", "reset s", "first step s", "total s"]
    cells = [
        [
            r["env"],
            r["run"],
            *(f"{r[k]:.1f}" for k in ("import", "make", "reset", "first_step", "total")),
        ]
        for r in result["runs"]
    ]
    return markdown_table(header, cells)
