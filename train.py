"""Train an SB3 agent on a pour-gym environment.

    python train.py --env PourGym/Pour-v0 --algo sac --objects train --timesteps 20000 --seed 0

Hyperparameters come from ``agents/hyperparams.yaml`` (keyed by environment id and
algorithm; ``--set key=value`` overrides one). Everything goes to ``--out`` (default
``runs/<env>_<algo>_<objects>_<obs_mode>_s<seed>``): checkpoints, ``progress.csv``,
``model.zip``, ``eval.json`` and ``eval.md`` (success, amount error and spill on every
container, those trained on marked). Run the same command again to resume.
"""

from __future__ import annotations

import argparse
import json
import sys

import yaml

from pour_gym.agents.evaluate import evaluation_table
from pour_gym.agents.training import ALGOS, TrainConfig, train
from pour_gym.errors import InputError


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, train, print the evaluation; returns the exit status."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="PourGym/Pour-v0")
    p.add_argument("--algo", choices=ALGOS, default="sac")
    p.add_argument("--objects", default="train", help="split, name, mesh path, or a,b,c")
    p.add_argument("--timesteps", type=int, default=20_000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--obs-mode", choices=["features", "state"], default="features")
    p.add_argument("--out", help="run directory")
    p.add_argument("--checkpoint-every", type=int, default=5_000)
    p.add_argument("--eval-objects", default="all")
    p.add_argument("--eval-episodes", type=int, default=5)
    p.add_argument("--env-kwargs", default="{}", help="JSON of more environment arguments")
    p.add_argument("--set", action="append", default=[], help="hyperparameter override k=v")
    p.add_argument("--json", action="store_true", help="print the evaluation as JSON")
    args = p.parse_args(argv)
    name = args.env.split("/")[-1]
    out = args.out or f"runs/{name}_{args.algo}_{args.objects}_{args.obs_mode}_s{args.seed}"
    try:
        overrides = {}
        for item in args.set:
            key, sep, value = item.partition("=")
            if not sep:
                raise InputError(f"--set takes key=value, not {item!r}")
            overrides[key] = yaml.safe_load(value)
        config = TrainConfig(
            env=args.env,
            algo=args.algo,
            objects=args.objects,
            timesteps=args.timesteps,
            seed=args.seed,
            obs_mode=args.obs_mode,
            out=out,
            checkpoint_every=args.checkpoint_every,
            eval_objects=args.eval_objects,
            eval_episodes=args.eval_episodes,
            env_kwargs=json.loads(args.env_kwargs),
            overrides=overrides,
        )
        result = train(config)
    except (InputError, json.JSONDecodeError) as exc:
        print(f"train.py: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(result, indent=2) if args.json else evaluation_table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
