"""Benchmark of the environments: real time, vector envs, the arm's cost."""

from __future__ import annotations

import statistics
import sys

import numpy as np
from tqdm import tqdm

from pour_gym.agents.policies.rollout import rollout
from pour_gym.agents.policies.scripted import ScriptedPourPolicy
from pour_gym.apps.bench.vector import (
    bench_family_memory,
    bench_memory,
    bench_native,
    family_memory_table,
    memory_table,
    native_table,
)
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


def _warmed(factory, threads: int | None):
    """An env from ``factory`` that has loaded its assets, fields and kernels (one step).

    The episodes timed after it start from a seeded reset, so the step changes nothing
    they compute.
    """
    env = factory() if threads is None else factory(num_threads=threads)
    env.reset(seed=2**31 - 1)
    env.step(env.action_space.sample())
    return env


def _paired_vec_rates(factory, steps: int, seed: int, threads: tuple[int | None, ...]) -> dict:
    """The same Pour-v0 work done by one env in turn and by SB3's SubprocVecEnv of two.

    The work: two episode streams, ``i`` = 0, 1, each started by ``reset(seed=seed + i)``
    (what ``SubprocVecEnv.seed(seed)`` gives worker ``i``) and fed ``steps`` random actions
    drawn beforehand, episodes restarting unseeded as they end (as SB3's workers restart
    them). One env runs stream 0 and then stream 1 in this process, at each of ``threads``
    (1, or None: its default); the vector env runs both at once, one per worker. The same
    actions on the same seeds give the same episodes bit for bit (the returns are
    compared), so the ratios compare equal work: comparing different seeds would compare
    fills of 200 to 400 particles, whose steps differ in cost by 2x.

    Returns:
        Env-steps per second by case (``one_thread`` / ``default_threads`` for one env,
        ``subproc_2``); ``same_work``: whether every case's summed rewards agree; and
        ``lockstep_bound``, per one-env case: the most two workers stepping in lockstep
        could gain over it, from its own step times (the sum of both streams' steps over
        the sum of the slower of each pair).
    """
    import functools
    import time

    from stable_baselines3.common.vec_env import SubprocVecEnv

    actions = None
    rates, returns, bound = {}, {}, {}
    for t in threads:
        env = _warmed(factory, t)
        if actions is None:  # drawn once, from the first env's space (they are all alike)
            env.action_space.seed(seed)
            actions = np.array(
                [[env.action_space.sample() for _ in range(2)] for _ in range(steps)]
            )
        total = 0.0
        seconds = np.zeros((2, steps))  # each step's, its episode's restart included
        for i in range(2):
            env.reset(seed=seed + i)
            for k in range(steps):
                start = time.perf_counter()
                _, reward, terminated, truncated, _ = env.step(actions[k, i])
                total += float(reward)
                if terminated or truncated:
                    env.reset()
                seconds[i, k] = time.perf_counter() - start
        env.close()
        name = "one_thread" if t == 1 else "default_threads"
        rates[name], returns[name] = float(2 * steps / seconds.sum()), total
        # Two workers in lockstep wait for the slower step each time: at best they do this
        # env's work in the sum of the slower of each pair of steps.
        bound[name] = float(seconds.sum() / seconds.max(axis=0).sum())
    vec = SubprocVecEnv([functools.partial(_warmed, factory, None)] * 2)
    vec.seed(seed)
    vec.reset()
    total = 0.0
    start = time.perf_counter()
    for k in range(steps):
        _, reward, _, _ = vec.step(actions[k])
        total += float(reward[0]) + float(reward[1])
    rates["subproc_2"] = 2 * steps / (time.perf_counter() - start)
    vec.close()
    returns["subproc_2"] = total
    # The summation order differs (stream by stream, or step by step): equal to rounding.
    same = bool(np.allclose(list(returns.values()), total, rtol=1e-9, atol=1e-9))
    return {**rates, "same_work": same, "lockstep_bound": bound}


def _pour_realtime(kwargs: dict, episodes: int, seed: int = 0, env_id: str = POUR_V0) -> float:
    """Simulated s per wall s of the scripted policy's episode steps, red cup -> broad cup."""
    env = make(env_id, source_objects="red_cup", target_objects="broad_cup", **kwargs)
    policy = ScriptedPourPolicy()
    # The first episode loads and compiles: not timed.
    runs = [rollout(env, policy, seed=seed + k) for k in range(episodes + 1)][1:]
    env.close()
    return sum(e.steps for e in runs) * env.unwrapped.dt / sum(e.step_seconds for e in runs)


ENV_SECTIONS = ("pour", "vec", "native", "memory", "family", "rows", "sensors")
# What runs without --sections: all but the half-hour family probe.
DEFAULT_SECTIONS = tuple(s for s in ENV_SECTIONS if s != "family")


def bench_envs(
    repeats: int = 3, steps: int = 600, sections: tuple[str, ...] = DEFAULT_SECTIONS
) -> dict:
    """Speed of the environments at their defaults, side by side in one run.

    - ``pour_v0``: the scripted policy pouring from the red cup into the broad cup, episode
      steps only: simulated seconds per wall second (``realtime``), steps per second, and
      the same with the fill of 1000 particles the first release used (``realtime_1000``).
    - ``panda_pour_v0``: the same episodes (same seeds, so the same fills) with the Panda
      holding the cup, each timed run right after Pour-v0's; its speed over Pour-v0's
      (``over_pour_v0``) is the median of the ratios of those pairs.
    - ``vec``: Pour-v0 env-steps per second under random actions: one env on one thread
      (``one_thread``) and at its default threads (``default_threads``) doing the same
      work as SB3's ``SubprocVecEnv`` of two workers (``subproc_2``): the same seeds and
      actions (:func:`_paired_vec_rates`; ``same_work`` says the returns agreed); and
      ``subproc_4``, four workers on their own seeds. ``ratios`` are medians of the
      ratios within each run, with the most lockstep allows (``lockstep_bound_...``).
    - ``rows``: the one-step environments alone and vectorised by two (Gymnasium's).
    - ``native``: the native vector env of 1 to 16 envs against one env on one thread
      and SubprocVecEnv(2), the same work (:func:`pour_gym.apps.bench.vector.bench_native`).
    - ``memory``: resident memory of a bare env's process, a worker, each extra native env,
      and of envs made and closed 50 times (:func:`pour_gym.apps.bench.vector.bench_memory`).
    - ``family``: resident memory of one Pour-v1 env over ``procedural:train`` for 1000
      random-action episodes (about 30 min; not in the default sections;
      :func:`pour_gym.apps.bench.vector.bench_family_memory`).
    - ``sensors``: ms per Pour-v0 step in each observation mode (:func:`bench_sensors`).

    Args:
        repeats: timed runs per case; the median is reported.
        steps: steps per timed run of the vector cases (600: several episodes, so that
            resets and long steps average out as they do in training).
        sections: which of ``pour`` (``pour_v0`` and ``panda_pour_v0``), ``vec`` (``vec``
            and ``ratios``), ``native``, ``memory``, ``family``, ``rows`` and ``sensors``
            to run.

    Raises:
        InputError: an unknown section.
    """
    import functools

    unknown = sorted(set(sections) - set(ENV_SECTIONS))
    if unknown:
        raise InputError(f"unknown bench envs sections {unknown}; choose from {ENV_SECTIONS}")
    counts = {"pour": 3, "vec": 4, "native": 1, "memory": 0, "family": 0, "rows": 6}
    counts["sensors"] = len(SENSOR_CASES)
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
        # Each run: the same work by one env (one thread, then its default threads) and by
        # two workers, back to back; the ratios are taken within each run.
        runs = []
        for r in range(repeats):
            runs.append(_paired_vec_rates(pour, steps, seed=100 * r, threads=(1, None)))
            bar.update(3)
        vec = {
            name: float(statistics.median(run[name] for run in runs))
            for name in ("default_threads", "one_thread", "subproc_2")
        }
        vec["subproc_4"] = median(lambda r: _env_rate(pour, "subproc_4", steps, seed=r))
        vec["same_work"] = all(run["same_work"] for run in runs)
        out["vec"] = vec
        out["ratios"] = {
            "subproc_2_over_one_thread": float(statistics.median(
                run["subproc_2"] / run["one_thread"] for run in runs
            )),
            "subproc_2_over_default": float(statistics.median(
                run["subproc_2"] / run["default_threads"] for run in runs
            )),
            "each_subproc_2_over_one_thread": [
                run["subproc_2"] / run["one_thread"] for run in runs
            ],
            "lockstep_bound_over_one_thread": float(statistics.median(
                run["lockstep_bound"]["one_thread"] for run in runs
            )),
        }  # fmt: skip
    if "native" in sections:
        out["native"] = bench_native(repeats, bar=bar)
    if "memory" in sections:
        out["memory"] = bench_memory()
    if "family" in sections:
        out["family"] = bench_family_memory()
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
            [
                "one env, default threads, both workers' episodes in turn",
                f"{v['default_threads']:.1f}",
            ],
            ["one env, num_threads=1, both workers' episodes in turn", f"{v['one_thread']:.1f}"],
            ["SubprocVecEnv, 2 workers", f"{v['subproc_2']:.1f}"],
            ["SubprocVecEnv, 4 workers (their own seeds)", f"{v['subproc_4']:.1f}"],
        ]
        parts += [
            markdown_table(["Pour-v0, random actions, SB3 vector env", "env-steps/s"], vector),
            "",
            f"The same work (same seeds and actions; returns equal: {v['same_work']}): "
            f"SubprocVecEnv(2) over one env on one thread "
            f"{q['subproc_2_over_one_thread']:.2f}x (runs: "
            + ", ".join(f"{x:.2f}x" for x in q["each_subproc_2_over_one_thread"])
            + f"); over one env at its default threads {q['subproc_2_over_default']:.2f}x. "
            f"Two workers in lockstep, each step waiting for the slower, could gain at most "
            f"{q['lockstep_bound_over_one_thread']:.2f}x over one thread on this work.",
            "",
        ]
    if "native" in result:
        parts += [native_table(result["native"]), ""]
    if "memory" in result:
        parts += [memory_table(result["memory"]), ""]
    if "family" in result:
        parts += [family_memory_table(result["family"]), ""]
    if "rows" in result:
        one_step = [[r["env"], r["mode"], f"{r['steps_per_s']:.1f}"] for r in result["rows"]]
        parts += [
            markdown_table(["environment", "mode", "steps/s (median)"], one_step, align="llr"),
            "",
        ]
    if "sensors" in result:
        parts += [sensors_table(result["sensors"]), ""]
    return "\n".join(parts).rstrip("\n")
