"""Benchmark of the environments: real time, vector envs, the arm's cost."""

from __future__ import annotations

import statistics
import sys

import numpy as np
from tqdm import tqdm

from pour_gym.agents.rollout import rollout
from pour_gym.agents.scripted import ScriptedPourPolicy
from pour_gym.envs import PANDA_POUR_V0, PARTICLE_DROP_V0, POUR_V0, TILT_POUR_V0, make
from pour_gym.errors import InputError
from pour_gym.report.tables import markdown_table


def _env_rate(factory, vector: str | None, steps: int, seed: int = 0) -> float:
    """Environment steps per second (all sub-environments together) over ``steps`` steps.

    ``vector``: None (one env), ``"sync"`` / ``"async"`` (Gymnasium's vector envs of two,
    async with Gymnasium's default start method), ``"dummy"`` / ``"subproc_<n>"`` (SB3's).
    Random actions; episodes restart as they end (their resets are in the time).
    """
    import time

    import gymnasium as gym

    if vector is None:
        env, n = factory(), 1
    elif vector in ("sync", "async"):
        cls = gym.vector.SyncVectorEnv if vector == "sync" else gym.vector.AsyncVectorEnv
        env, n = cls([factory, factory]), 2
    else:
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

        n = 1 if vector == "dummy" else int(vector.split("_")[1])
        env = DummyVecEnv([factory]) if vector == "dummy" else SubprocVecEnv([factory] * n)
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


def _pour_realtime(kwargs: dict, episodes: int, seed: int = 0, env_id: str = POUR_V0) -> float:
    """Simulated s per wall s of the scripted policy's episode steps, red cup -> broad cup."""
    env = make(env_id, source_objects="red_cup", target_objects="broad_cup", **kwargs)
    policy = ScriptedPourPolicy()
    # The first episode loads and compiles: not timed.
    runs = [rollout(env, policy, seed=seed + k) for k in range(episodes + 1)][1:]
    env.close()
    return sum(e.steps for e in runs) * env.unwrapped.dt / sum(e.step_seconds for e in runs)


ENV_SECTIONS = ("pour", "vec", "rows", "sensors")


def bench_envs(
    repeats: int = 3, steps: int = 600, sections: tuple[str, ...] = ENV_SECTIONS
) -> dict:
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
    - ``sensors``: ms per Pour-v0 step in each observation mode (:func:`bench_sensors`).

    Args:
        repeats: timed runs per case; the median is reported.
        steps: steps per timed run of the vector cases (600: several episodes, so that
            resets and long steps average out as they do in training).
        sections: which of ``pour`` (``pour_v0`` and ``panda_pour_v0``), ``vec`` (``vec``
            and ``ratios``), ``rows`` and ``sensors`` to run.

    Raises:
        InputError: an unknown section.
    """
    import functools

    unknown = sorted(set(sections) - set(ENV_SECTIONS))
    if unknown:
        raise InputError(f"unknown bench envs sections {unknown}; choose from {ENV_SECTIONS}")
    counts = {"pour": 3, "vec": 4, "rows": 6, "sensors": len(SENSOR_CASES)}
    bar = tqdm(total=sum(counts[c] for c in sections) * repeats, desc="bench envs", file=sys.stderr)
    out: dict = {}

    def median(fn) -> float:
        runs = []
        for r in range(repeats):
            runs.append(fn(r))
            bar.update()
        return float(statistics.median(runs))

    if "pour" in sections:
        # Pour-v0 and PandaPour-v0 alternate, run by run: the ratio is taken within each
        # pair (this machine's speed drifts by 2x over minutes), and its median reported.
        pairs = []
        for r in range(repeats):
            alone = _pour_realtime({}, 2, seed=100 * r)
            bar.update()
            held = _pour_realtime({}, 2, seed=100 * r, env_id=PANDA_POUR_V0)
            bar.update()
            pairs.append((alone, held))
        realtime = float(statistics.median(a for a, _ in pairs))
        panda = float(statistics.median(b for _, b in pairs))
        realtime_1000 = median(
            lambda r: _pour_realtime({"source_particles": 1000}, 2, seed=100 * r)
        )
        out["pour_v0"] = {
            "realtime": realtime,
            "steps_per_s": realtime / 0.1,
            "realtime_1000": realtime_1000,
        }
        out["panda_pour_v0"] = {
            "realtime": panda,
            "steps_per_s": panda / 0.1,
            "over_pour_v0": float(statistics.median(b / a for a, b in pairs)),
        }
    if "vec" in sections:
        pour = functools.partial(make, POUR_V0)
        single = functools.partial(make, POUR_V0, num_threads=1)
        # The cases a ratio is taken between alternate run by run, as above.
        runs: dict[str, list[float]] = {"dummy_1": [], "one_thread": [], "subproc_2": []}
        for r in range(repeats):
            for name, factory, mode in (
                ("dummy_1", pour, "dummy"),
                ("one_thread", single, "dummy"),
                ("subproc_2", pour, "subproc_2"),
            ):
                runs[name].append(_env_rate(factory, mode, steps, seed=r))
                bar.update()
        vec = {name: float(statistics.median(v)) for name, v in runs.items()}
        vec["subproc_4"] = median(lambda r: _env_rate(pour, "subproc_4", steps, seed=r))
        out["vec"] = vec
        out["ratios"] = {
            "subproc_2_over_one_thread": float(statistics.median(
                b / a for a, b in zip(runs["one_thread"], runs["subproc_2"], strict=True)
            )),
            "subproc_2_over_default": float(statistics.median(
                b / a for a, b in zip(runs["dummy_1"], runs["subproc_2"], strict=True)
            )),
        }  # fmt: skip
    if "rows" in sections:
        rows = []
        for env_id in (PARTICLE_DROP_V0, TILT_POUR_V0):
            make_one = functools.partial(make, env_id)
            for mode in (None, "sync", "async"):
                rate = median(lambda r, m=make_one, mode=mode: _env_rate(m, mode, 60, seed=r))
                rows.append({"env": env_id, "mode": mode or "single", "steps_per_s": rate})
        out["rows"] = rows
    if "sensors" in sections:
        out["sensors"] = bench_sensors(repeats, bar=bar)
    bar.close()
    return out


SENSOR_CASES = ("features", "depth", "rgb", "points", ("features", "depth"))


def bench_sensors(repeats: int = 3, steps: int = 300, bar: tqdm | None = None) -> dict:
    """What each observation mode costs on a Pour-v0 step, one thread, side by side.

    Pour-v0 on the red cup, ``num_threads=1`` (how RL workers run), random actions with
    the same seeds in every mode: the episodes are the same (the sensors' randomness is a
    stream of their own), so the difference is the observation. The modes alternate run
    by run; ``over_features`` is the median over runs of a mode's ms per step over the
    features mode's in the same run.

    Args:
        repeats: timed runs per mode.
        steps: steps per timed run.
        bar: a progress bar to advance (one tick per run), or None.

    Returns:
        ``{"rows": [{"obs_mode", "ms_per_step", "over_features"}], "steps", "repeats"}``.
    """
    import functools

    ms: dict[str, list[float]] = {_mode_name(m): [] for m in SENSOR_CASES}
    for r in range(repeats):
        for mode in SENSOR_CASES:
            factory = functools.partial(
                make, POUR_V0, objects="red_cup", num_threads=1, obs_mode=mode
            )
            ms[_mode_name(mode)].append(1e3 / _env_rate(factory, None, steps, seed=r))
            if bar is not None:
                bar.update()
    base = ms["features"]
    rows = [
        {
            "obs_mode": name,
            "ms_per_step": float(statistics.median(v)),
            "over_features": float(statistics.median(a / b for a, b in zip(v, base, strict=True))),
        }
        for name, v in ms.items()
    ]
    return {"rows": rows, "steps": steps, "repeats": repeats}


def _mode_name(mode) -> str:
    return mode if isinstance(mode, str) else "+".join(mode)


def sensors_table(result: dict) -> str:
    """Markdown table of :func:`bench_sensors`."""
    rows = [
        [r["obs_mode"], f"{r['ms_per_step']:.2f}", f"{r['over_features']:.2f}x"]
        for r in result["rows"]
    ]
    return markdown_table(
        ["Pour-v0, one thread, obs_mode (84 x 84, 1024 points)", "ms per step (median)",
         "over features"], rows, align="lrr",
    )  # fmt: skip


def envs_table(result: dict) -> str:
    """Markdown tables of :func:`bench_envs` (the sections it ran)."""
    parts = []
    if "pour_v0" in result:
        p, a = result["pour_v0"], result["panda_pour_v0"]
        realtime = [
            ["defaults (fill T + 100)", f"{p['realtime']:.2f}"],
            ["1000 particles", f"{p['realtime_1000']:.2f}"],
            ["PandaPour-v0, the Panda holding the cup (defaults, the same episodes)",
             f"{a['realtime']:.2f} ({a['over_pour_v0']:.2f}x Pour-v0)"],
        ]  # fmt: skip
        parts += [markdown_table(["Pour-v0, scripted policy, red cup -> broad cup",
                                  "simulated s per wall s"], realtime), ""]  # fmt: skip
    if "vec" in result:
        v, q = result["vec"], result["ratios"]
        vector = [
            ["DummyVecEnv, 1 env, default threads", f"{v['dummy_1']:.1f}"],
            ["DummyVecEnv, 1 env, num_threads=1", f"{v['one_thread']:.1f}"],
            ["SubprocVecEnv, 2 workers", f"{v['subproc_2']:.1f}"],
            ["SubprocVecEnv, 4 workers", f"{v['subproc_4']:.1f}"],
        ]
        parts += [
            markdown_table(["Pour-v0, random actions, SB3 vector env", "env-steps/s"], vector),
            "",
            f"SubprocVecEnv(2) over one env on one thread: "
            f"{q['subproc_2_over_one_thread']:.2f}x; over one env at its default threads: "
            f"{q['subproc_2_over_default']:.2f}x",
            "",
        ]
    if "rows" in result:
        one_step = [[r["env"], r["mode"], f"{r['steps_per_s']:.1f}"] for r in result["rows"]]
        parts += [
            markdown_table(["environment", "mode", "steps/s (median)"], one_step, align="llr"),
            "",
        ]
    if "sensors" in result:
        parts += [sensors_table(result["sensors"]), ""]
    return "\n".join(parts).rstrip("\n")
