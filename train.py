"""Train an SB3 agent on a pour-gym environment.

    python train.py --env PourGym/Pour-v0 --algo sac --objects train --timesteps 20000 --seed 0

Hyperparameters come from ``agents/hyperparams.yaml`` (keyed by environment id and
algorithm; ``--set key=value`` overrides one). Everything goes to ``--out`` (default
``runs/<env>_<algo>_<objects>_<obs_mode>_s<seed>``): checkpoints, ``progress.csv``,
``curve.png``, ``model.zip``, ``eval.json`` and ``eval.md`` (success, amount error and
spill on every container, those trained on marked). Run the same command again to resume.
The options are the fields of :class:`pour_gym.agents.training.TrainConfig`.
"""

from __future__ import annotations

import json
import sys

from pour_gym.agents.evaluate import evaluation_table
from pour_gym.agents.training import config_from_args, config_parser, train
from pour_gym.errors import InputError


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, train, print the evaluation; returns the exit status."""
    parser = config_parser(__doc__.split("\n\n")[0])
    try:
        args = parser.parse_args(argv)
        config = config_from_args(args)
        result = train(config)
    except (InputError, json.JSONDecodeError) as exc:
        print(f"train.py: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(result, indent=2) if args.json else evaluation_table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
