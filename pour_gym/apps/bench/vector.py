"""Benchmark of the native vector env: env-steps per second by number of envs, and memory.

``pour-gym bench envs --sections native`` (speed) and ``--sections memory`` (resident
memory of processes made for the purpose: a bare env, a worker, each extra env of a native
vector env, environments made and closed over and over).
"""

from __future__ import annotations

import functools
import json
import statistics
import subprocess
import sys
import time

import numpy as np

from pour_gym.envs import POUR_V0, POUR_V1, make
from pour_gym.report.tables import markdown_table

NATIVE_SIZES = (1, 2, 4, 8, 16)


def _streams(count: int, steps: int, seed: int, space) -> np.ndarray:
    """Random actions, ``(steps, count, dim)``: stream ``i`` feeds env ``i``."""
    space.seed(seed)
    return np.array([[space.sample() for _ in range(count)] for _ in range(steps)])


def native_round(steps: int, seed: int, sizes=NATIVE_SIZES, objects: str = "red_cup") -> dict:
    """One round of the same Pour-v0 work by one env, SubprocVecEnv(2) and native envs.

    The work: ``max(sizes)`` episode streams, stream ``i`` started by ``reset(seed=seed +
    i)`` and fed ``steps`` random actions drawn beforehand, episodes restarting unseeded as
    they end (next-step autoreset, as SB3's and Gymnasium's envs restart them). One env on
    one thread runs the streams in turn (each stream timed); a native vector env of N envs
    runs streams 0 to N-1 at once; SB3's ``SubprocVecEnv`` of two workers runs streams 0
    and 1. Every stream's summed reward is compared with the one env's: the same work.

    Returns:
        ``one_thread`` (env-steps/s of one env over streams 0 to N-1, by N),
        ``native`` (by N), ``subproc_2``, ``same_work`` (every return bit for bit).
    """
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from pour_gym.envs.vector import PourVectorEnv

    count = max(sizes)
    kwargs = {"objects": objects}
    env = make(POUR_V0, num_threads=1, **kwargs)
    actions = _streams(count, steps, seed, env.action_space)
    env.reset(seed=2**31 - 1)
    env.step(actions[0, 0])  # warm: containers, fields and kernel loaded
    seconds, returns = np.zeros(count), np.zeros(count)
    for i in range(count):
        env.reset(seed=seed + i)
        start, total, ended = time.perf_counter(), 0.0, False
        for k in range(steps):
            if ended:
                env.reset()
                ended = False
                continue
            _, reward, terminated, truncated, _ = env.step(actions[k, i])
            total += float(reward)
            ended = terminated or truncated
        seconds[i], returns[i] = time.perf_counter() - start, total
    env.close()
    same = True
    native = {}
    for n in sizes:
        venv = PourVectorEnv(POUR_V0, n, **kwargs)
        venv.reset(seed=2**31 - 1)
        venv.step(actions[0, :n])
        venv.reset(seed=seed)
        totals = np.zeros(n)
        start = time.perf_counter()
        for k in range(steps):
            _, reward, _, _, _ = venv.step(actions[k, :n])
            totals += reward
        native[n] = n * steps / (time.perf_counter() - start)
        venv.close()
        same = same and bool(np.array_equal(totals, returns[:n]))
    factory = functools.partial(make, POUR_V0, **kwargs)  # a worker imports the ids with it
    vec = SubprocVecEnv([factory] * 2, start_method="forkserver")
    vec.seed(seed)
    vec.reset()
    vec.step(actions[0, :2])
    vec.seed(seed)
    vec.reset()
    totals = np.zeros(2)
    start = time.perf_counter()
    for k in range(steps):
        _, reward, _, _ = vec.step(actions[k, :2])
        totals += reward
    subproc = 2 * steps / (time.perf_counter() - start)
    vec.close()
    # SB3 restarts an episode in the step that ends it, not the next: its work differs by
    # the restarts' steps, so only its rate is kept (not its returns).
    one = {n: n * steps / float(seconds[:n].sum()) for n in sizes}
    return {"one_thread": one, "native": native, "subproc_2": subproc, "same_work": same}


def bench_native(repeats: int = 3, steps: int = 300, sizes=NATIVE_SIZES, bar=None) -> dict:
    """Native vector env against one one-thread env and SubprocVecEnv(2), over rounds.

    Returns:
        ``rows`` per N: the median env-steps/s and the median within-round ratio over one
        env on one thread doing the same streams (``over_one_thread``), with every
        round's ratio; ``subproc_2`` likewise; ``same_work``.
    """
    rounds = []
    for r in range(repeats):
        rounds.append(native_round(steps, seed=1000 * (r + 1), sizes=sizes))
        if bar is not None:
            bar.update()
    rows = []
    for n in sizes:
        ratios = [x["native"][n] / x["one_thread"][n] for x in rounds]
        rows.append({
            "envs": n,
            "steps_per_s": float(statistics.median(x["native"][n] for x in rounds)),
            "one_thread_steps_per_s": float(statistics.median(x["one_thread"][n] for x in rounds)),
            "over_one_thread": float(statistics.median(ratios)),
            "each_over_one_thread": ratios,
        })  # fmt: skip
    sub = [x["subproc_2"] / x["one_thread"][2] for x in rounds]
    return {
        "rows": rows,
        "subproc_2": {
            "steps_per_s": float(statistics.median(x["subproc_2"] for x in rounds)),
            "over_one_thread": float(statistics.median(sub)),
            "each_over_one_thread": sub,
        },
        "same_work": all(x["same_work"] for x in rounds),
        "steps": steps,
        "repeats": repeats,
    }


def native_table(result: dict) -> str:
    """Markdown table of :func:`bench_native`."""
    rows = [
        [
            f"native, {r['envs']} env{'s' if r['envs'] > 1 else ''}",
            f"{r['steps_per_s']:.1f}",
            f"{r['over_one_thread']:.2f}x",
            ", ".join(f"{x:.2f}" for x in r["each_over_one_thread"]),
        ]
        for r in result["rows"]
    ]
    s = result["subproc_2"]
    rows.append([
        "SubprocVecEnv, 2 workers", f"{s['steps_per_s']:.1f}", f"{s['over_one_thread']:.2f}x",
        ", ".join(f"{x:.2f}" for x in s["each_over_one_thread"]),
    ])  # fmt: skip
    head = ["Pour-v0, red cup, random actions", "env-steps/s (median)",
            "over one env, one thread", "each round"]  # fmt: skip
    note = (
        f"{result['repeats']} rounds of {result['steps']} steps per env; in each round one "
        "env on one thread runs the same seeded streams in turn (the ratios are within a "
        f"round); every native env's return equals the one env's, bit for bit: "
        f"{result['same_work']}."
    )
    return "\n".join([markdown_table(head, rows, align="lrrl"), "", note])


# ---------------------------------------------------------------------- memory
_RSS = "int(open('/proc/self/status').read().split('VmRSS:')[1].split()[0]) / 1024"

_BARE = f"""
import json, gymnasium as gym, pour_gym
env = gym.make({POUR_V0!r}, objects="red_cup", num_threads=1)
env.reset(seed=0)
for _ in range(50):
    env.step(env.action_space.sample())
print(json.dumps({{"rss": {_RSS}}}))
"""

_NATIVE = f"""
import json, sys, gymnasium as gym, pour_gym
n = int(sys.argv[1])
venv = gym.make_vec({POUR_V0!r}, num_envs=n, objects="red_cup")
venv.reset(seed=0)
for _ in range(50):
    venv.step(venv.action_space.sample())
print(json.dumps({{"rss": {_RSS}}}))
"""

_WORKER = f"""
import functools, json
from stable_baselines3.common.vec_env import SubprocVecEnv
from pour_gym.envs import make
def rss(pid):
    return int(open(f"/proc/{{pid}}/status").read().split("VmRSS:")[1].split()[0]) / 1024
factory = functools.partial(make, {POUR_V0!r}, objects="red_cup")
venv = SubprocVecEnv([factory] * 2, start_method="forkserver")
venv.reset()
for _ in range(50):
    venv.step([venv.action_space.sample() for _ in range(2)])
print(json.dumps({{"rss": max(rss(p.pid) for p in venv.processes)}}))
venv.close()
"""

_ROUNDS = f"""
import json, sys, gymnasium as gym, pour_gym
rounds = int(sys.argv[1])
seen = []
for k in range(rounds):
    env = gym.make({POUR_V0!r}, objects="test")
    env.reset(seed=k)
    for _ in range(5):
        env.step(env.action_space.sample())
    env.close()
    seen.append({_RSS})
print(json.dumps({{"rss": seen}}))
"""


_FAMILY = f"""
import json, sys, gymnasium as gym, pour_gym
episodes = int(sys.argv[1])
env = gym.make({POUR_V1!r}, objects="procedural:train", num_threads=1)
env.action_space.seed(0)
env.reset(seed=0)
done, steps, seen = 0, 0, []
while done < episodes:
    _, _, terminated, truncated, _ = env.step(env.action_space.sample())
    steps += 1
    if terminated or truncated:
        done += 1
        env.reset()
        if done % 50 == 0:
            seen.append({_RSS})
print(json.dumps({{"rss": seen, "steps": steps}}))
"""


def bench_family_memory(episodes: int = 1000) -> dict:
    """Resident memory (MB) of one Pour-v1 env over ``procedural:train``, random actions.

    Make the family ready first (``pour-gym build-assets --objects procedural:train``), or
    the probe labels each member and computes its field as it meets it. The process's
    memory is read every 50 episodes.

    Returns:
        ``{"episodes", "steps", "each_50": [MB...], "max", "last"}``.
    """
    doc = _measure(_FAMILY, str(episodes))
    seen = doc["rss"]
    return {"episodes": episodes, "steps": doc["steps"], "each_50": seen, "max": max(seen),
            "last": seen[-1]}  # fmt: skip


def _measure(script: str, *args: str) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", script, *args], capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        raise RuntimeError(f"a memory probe failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def bench_memory(rounds: int = 50, envs: int = 8) -> dict:
    """Resident memory (MB) of processes made for the purpose, each measured alone.

    - ``bare``: a process that made one Pour-v0 env (red cup, one thread), reset it and
      took 50 random steps;
    - ``subproc_worker``: the larger of two SB3 ``SubprocVecEnv`` workers after the same;
    - ``native_1`` / ``native_<envs>``: a native vector env of 1 and ``envs`` envs after
      50 steps; ``per_extra_env``: the difference over ``envs - 1``;
    - ``rounds``: a process that makes a Pour-v0 env over the test split, resets it, steps
      it 5 times and closes it, ``rounds`` times: its memory after each round (``each``),
      the median over the first ten rounds and over the last ten, and the growth between
      (a round's memory depends on the two containers it drew: the medians smooth that).
    """
    bare = _measure(_BARE)["rss"]
    worker = _measure(_WORKER)["rss"]
    one = _measure(_NATIVE, "1")["rss"]
    many = _measure(_NATIVE, str(envs))["rss"]
    seen = _measure(_ROUNDS, str(rounds))["rss"]
    return {
        "bare": bare,
        "subproc_worker": worker,
        "native_1": one,
        f"native_{envs}": many,
        "envs": envs,
        "per_extra_env": (many - one) / (envs - 1),
        "rounds": {
            "count": rounds,
            "first": float(statistics.median(seen[:10])),
            "last": float(statistics.median(seen[-10:])),
            "growth": float(statistics.median(seen[-10:]) - statistics.median(seen[:10])),
            "each": seen,
        },
    }


def family_memory_table(result: dict) -> str:
    """Markdown table of :func:`bench_family_memory`."""
    rows = [
        [f"one Pour-v1 env over procedural:train, {result['episodes']} random-action episodes "
         f"({result['steps']:,} steps): after 50 / at most / after the last",
         f"{result['each_50'][0]:.0f} / {result['max']:.0f} / {result['last']:.0f}"],
    ]  # fmt: skip
    return markdown_table(["process", "resident memory, MB"], rows, align="lr")


def memory_table(result: dict) -> str:
    """Markdown table of :func:`bench_memory`."""
    n, r = result["envs"], result["rounds"]
    rows = [
        ["a bare Pour-v0 process (one env, 50 steps)", f"{result['bare']:.0f}"],
        ["a SubprocVecEnv worker (the larger of two)", f"{result['subproc_worker']:.0f}"],
        ["a native vector env of 1 env", f"{result['native_1']:.0f}"],
        [f"a native vector env of {n} envs", f"{result[f'native_{n}']:.0f}"],
        ["each extra env of a native vector env", f"{result['per_extra_env']:.1f}"],
        [f"make, reset, 5 steps, close, {r['count']} times: rounds 1-10 / the last 10 (medians)",
         f"{r['first']:.0f} / {r['last']:.0f} ({r['growth']:+.1f})"],
    ]  # fmt: skip
    return markdown_table(["process", "resident memory, MB"], rows, align="lr")
