"""Train an SB3 agent on a pour-gym environment: the same command as ``pour-gym train``.

    python train.py --env PourGym/Pour-v0 --algo bc --objects red_cup --timesteps 2000

``python train.py --help`` lists the options (the fields of
:class:`pour_gym.agents.training.TrainConfig`); the recipes are ``agents/hyperparams.yaml``.
"""

import sys

from pour_gym.apps.cli import main

if __name__ == "__main__":
    sys.exit(main(["train", *sys.argv[1:]]))
