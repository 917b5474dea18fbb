"""Where a Pour-v1 model spills and where it stops, episode by episode (mean action).

Run from the repository's root: ``python docs/learning-from-reward/spill_diagnosis.py
MODEL.zip EPISODES`` (episodes over ``procedural:test`` at seeds 60000 on). Per episode:
the source and target members, the target amount, what was poured and spilled, the
largest tilt, the steps, and at the first step with a particle spilled the tilt, the lip
from the target's rim centre in target rim radii (x: the pouring point is -0.5), the
lip's height over the rim (m) and the particles poured and in flight.
"""

import sys
import warnings

import gymnasium as gym

import pour_gym  # noqa: F401  (registers the envs)
from pour_gym.agents.evaluation.evaluate import load_policy

warnings.filterwarnings("ignore")


def main(model: str, episodes: int) -> None:
    """Print one line per episode of ``model`` over ``procedural:test``."""
    loaded = load_policy(model, actions="mean")
    env = gym.make(loaded.env_id, objects="procedural:test", **loaded.env_kwargs, num_threads=1)
    u = env.unwrapped
    for ep in range(episodes):
        obs, info = env.reset(seed=60000 + ep)
        first, most_tilt, steps = None, 0.0, 0
        for steps in range(1, 301):
            obs, _, terminated, truncated, info = env.step(loaded.policy(obs))
            most_tilt = max(most_tilt, u.tilt)
            if first is None and info["spilled"] > 0:
                g = u.target.asset.geometry
                rim = u.target.to_world(g.rim_center)
                dx, dy = (u.lip[:2] - rim[:2]) / g.rim_radius
                first = (
                    f"step {steps}, tilt {u.tilt:.0f} deg, lip x {dx:+.2f} y {dy:+.2f} radii,"
                    f" {u.lip[2] - rim[2]:.3f} m up, poured {info['poured']},"
                    f" in flight {info['in_flight']}"
                )
            if terminated or truncated:
                break
        print(
            f"{ep}: {info['source']} -> {info['target']}, T {info['target_amount']}, poured "
            f"{info['poured']}, spilled {info['spilled']}, most tilt {most_tilt:.0f} deg, "
            f"{steps} steps; first spill: {first or 'none'}",
            flush=True,
        )
    env.close()


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
