"""Soak test: random actions for many episodes, counted by rules independent of the env's.

What an RL agent does first is act at random for thousands of episodes. This runs that over
containers and counts what must never happen, with definitions that do not trust the
environment's own bookkeeping:

- an exception from ``reset`` or ``step`` (an action from the action space never raises);
- a false ending (Pour-v0): the episode terminated with nothing in the target and at most
  2 particles outside the source, after a largest tilt below 30 degrees;
- particles lost: a world census (every particle in exactly one container or elsewhere)
  that does not add up to the particles the episode started with;
- wall violations: steps after which a particle's centre lies inside a container's
  material (:meth:`pour_gym.sim.World.check_walls`).

Corrections (particles the fluid put back out of a wall they had tunnelled into) are
counted too: they are the fluid doing its job, a measure of how hard the motion was.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from tqdm import tqdm

from pour_gym.agents.policies.rollout import Step, rollout
from pour_gym.envs import POUR_V0, make, task_of
from pour_gym.errors import SimulationError
from pour_gym.report.tables import markdown_table

FALSE_ENDING_TILT = 30.0  # deg
FALSE_ENDING_OUTSIDE = 2  # particles
# What a soak counts, per container and in all.
COUNTS = ("episodes", "exceptions", "false_endings", "particles_lost", "wall_violations",
          "corrections", "steps")  # fmt: skip


def user_meshes(folder: str | Path) -> list[str]:
    """Write the meshes users bring (:mod:`pour_gym.objects.user_meshes`) as files.

    Returns:
        Paths of a two-body mug with 5 mm walls (OBJ) and a cup with 3 mm walls (STL).
    """
    from pour_gym.objects.user_meshes import thin_walled_cup, two_body_mug

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, mesh in (("two_body_mug.obj", two_body_mug()), ("thin_cup.stl", thin_walled_cup())):
        path = folder / name
        if not path.is_file():
            mesh.export(path)
        out.append(str(path))
    return out


def soak(
    env_id: str = POUR_V0,
    objects: list[str] | None = None,
    episodes: int = 20,
    steps: int = 250,
    seed: int = 0,
    env_kwargs: dict | None = None,
) -> dict:
    """Random-action episodes over containers; the counts of what must not happen.

    For Pour-v0 each container is the source of its episodes, the target drawn from all
    of them; the one-step environments use it as their container.

    Args:
        env_id: a registered ``PourGym/`` id.
        objects: containers (names or mesh paths; default: the catalogue and two meshes
            made the way users' are, written to the cache).
        episodes: episodes per container.
        steps: most steps per episode.
        seed: seed of the first episode and of the actions.
        env_kwargs: more keyword arguments for ``gymnasium.make``.

    Returns:
        ``{"episodes", "exceptions", "false_endings", "particles_lost", "wall_violations",
        "corrections", "steps_per_s", "steps", "by_object": {...}, "errors": [...]}``.
    """
    from pour_gym.assets import CATALOGUE
    from pour_gym.io.cache import cache_dir

    if objects is None:
        objects = [*CATALOGUE, *user_meshes(cache_dir("soak"))]
    pour = task_of(env_id).pours
    totals = dict.fromkeys(COUNTS, 0)
    by_object: dict[str, dict] = {}
    errors: list[str] = []
    wall = 0.0
    bar = tqdm(total=len(objects) * episodes, desc=f"soak {env_id}", file=sys.stderr)
    for k, name in enumerate(objects):
        kwargs = dict(env_kwargs or {})
        if pour:
            kwargs.update(source_objects=[name], target_objects=list(objects))
        else:
            kwargs.update(objects=[name])
        counts = dict.fromkeys(totals, 0)
        try:
            env = make(env_id, **kwargs)
        except Exception as exc:  # a container the env refuses is reported, not fatal
            errors.append(f"{name}: make: {type(exc).__name__}: {exc}")
            counts["exceptions"] += 1
            by_object[name] = counts
            bar.update(episodes)
            continue
        env.action_space.seed(seed + k)
        for ep in range(episodes):
            t = time.perf_counter()
            outcome = _episode(env, seed + 1000 * k + ep, steps, pour)
            wall += time.perf_counter() - t
            for key, value in outcome.items():
                if key != "error":
                    counts[key] += value
            if outcome.get("error") and len(errors) < 10:
                errors.append(f"{name}, episode {ep}: {outcome['error']}")
            bar.update()
        env.close()
        by_object[name] = counts
        for key in totals:
            totals[key] += counts[key]
    bar.close()
    return {
        **totals,
        "steps_per_s": totals["steps"] / wall if wall > 0 else 0.0,
        "env": env_id,
        "episodes_per_object": episodes,
        "by_object": by_object,
        "errors": errors,
    }


def _episode(env, seed: int, steps: int, pour: bool) -> dict:
    """One random-action episode; its counts (and the first error's text, if one)."""
    out = dict.fromkeys(COUNTS, 0)
    out["episodes"] = 1
    u = env.unwrapped
    max_tilt = [0.0]
    start = [0]

    def check(step: Step) -> bool:
        """After each step: the census, the walls; a false ending; stop at ``steps``."""
        out["steps"] += 1
        out["corrections"] += u.world.corrections
        lost = start[0] - u.world.census().total
        if lost:
            out["particles_lost"] = max(out["particles_lost"], lost)
        try:
            u.world.check_walls()
        except SimulationError as exc:
            out["wall_violations"] += 1
            out.setdefault("error", str(exc))
        info = step.info
        if pour:
            max_tilt[0] = max(max_tilt[0], info["tilt_deg"])
            # A failure (PandaPour-v0: the arm touched the target) is an ending.
            if step.terminated and info["poured"] == 0 and not info.get("failure"):
                outside = info["fill"] - info["in_source"]
                if outside <= FALSE_ENDING_OUTSIDE and max_tilt[0] < FALSE_ENDING_TILT:
                    out["false_endings"] += 1
        return step.index >= steps

    class RandomActions:
        """Random actions; at each reset, the particles the episode starts with."""

        def reset(self) -> None:
            start[0] = u.world.fluid.count

        def __call__(self, obs):
            return env.action_space.sample()

    try:
        episode = rollout(env, RandomActions(), seed=seed, on_step=check)
        info = episode.reset_info
        if pour and info["in_source"] != info["fill"]:
            out["particles_lost"] += info["fill"] - info["in_source"]
            out["error"] = f"reset: {info['in_source']} of {info['fill']} in the source"
    except Exception as exc:  # counted and reported: the point of a soak
        out["exceptions"] += 1
        out["error"] = f"{type(exc).__name__}: {exc}"
    return out


def soak_liquids(
    liquids: list[str],
    env_id: str = POUR_V0,
    objects: list[str] | None = None,
    episodes: int = 20,
    steps: int = 250,
    seed: int = 0,
) -> dict:
    """:func:`soak` once per liquid (each container with each), the counts in all and by liquid.

    Args:
        liquids: liquids' preset names (:data:`pour_gym.fluid.liquid.PRESETS`).
        env_id: as :func:`soak`.
        objects: as :func:`soak`.
        episodes: as :func:`soak`.
        steps: as :func:`soak`.
        seed: as :func:`soak` (the same per liquid: the same containers, starts and
            actions, another liquid).

    Returns:
        :func:`soak`'s document over all liquids, ``by_object`` keyed ``"name [liquid]"``,
        and ``by_liquid``: each liquid's totals.
    """
    from pour_gym.fluid.liquid import liquid_of

    for name in liquids:
        liquid_of(name)  # an unknown name fails before any work
    docs = {name: soak(env_id, objects, episodes, steps, seed, {"liquid": name})
            for name in liquids}  # fmt: skip
    totals = {k: sum(d[k] for d in docs.values()) for k in COUNTS}
    wall = sum(d["steps"] / d["steps_per_s"] for d in docs.values() if d["steps_per_s"] > 0)
    return {
        **totals,
        "steps_per_s": totals["steps"] / wall if wall > 0 else 0.0,
        "env": env_id,
        "episodes_per_object": episodes,
        "by_object": {
            f"{obj} [{name}]": counts
            for name, d in docs.items()
            for obj, counts in d["by_object"].items()
        },
        "by_liquid": {
            name: {k: d[k] for k in (*COUNTS, "steps_per_s")} for name, d in docs.items()
        },
        "errors": [f"[{name}] {e}" for name, d in docs.items() for e in d["errors"]][:10],
    }


def soak_table(doc: dict) -> str:
    """A markdown table of :func:`soak` per container, with the totals."""
    keys = COUNTS[:-1]  # not the steps
    rows = [
        [Path(name).name, *(counts[k] for k in keys)] for name, counts in doc["by_object"].items()
    ]
    for liquid, counts in doc.get("by_liquid", {}).items():
        rows.append([f"all [{liquid}]", *(counts[k] for k in keys)])
    rows.append(["**all**", *(f"**{doc[k]}**" for k in keys)])
    lines = [markdown_table(["container", *keys], rows)]
    for liquid, counts in doc.get("by_liquid", {}).items():
        lines.append(f"{liquid}: {counts['steps_per_s']:.1f} steps/s")
    lines.append(f"\n{doc['env']}, random actions: {doc['steps_per_s']:.1f} steps/s")
    if doc["errors"]:
        lines.append("\nfirst errors:\n" + "\n".join(f"- {e}" for e in doc["errors"]))
    return "\n".join(lines)
