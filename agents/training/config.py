"""What a training run does: :class:`TrainConfig`, which is also the command line.

``train.py`` and ``pour-gym train`` build their options from the fields of
:class:`TrainConfig` (:func:`config_parser`): a field is a ``--flag`` with its one-line
doc as the help, so the two commands and the Python API cannot disagree.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from pour_gym.envs import POUR_V0
from pour_gym.envs.observations import OBS_MODES
from pour_gym.errors import InputError

# Algorithm name -> "module:class"; imported when used (sb3-contrib is optional).
ALGORITHMS = {
    "sac": "stable_baselines3:SAC",
    "ppo": "stable_baselines3:PPO",
    "td3": "stable_baselines3:TD3",
    "tqc": "sb3_contrib:TQC",
    # Augmented Random Search (sb3-contrib's) with every candidate of an update scored on
    # the same episodes (agents/training/ars.py): a linear policy searched from the reward.
    "ars": "pour_gym.agents.training.ars:PairedARS",
    # Behaviour cloning: TQC's actor cloned from the scripted expert's demonstrations, with
    # TQC's own updates off in its recipe (gradient_steps: 0). A TQC model on disk.
    "bc": "sb3_contrib:TQC",
}


def algorithm(name: str):
    """The SB3 algorithm class of a name in :data:`ALGORITHMS`.

    Raises:
        InputError: an unknown name, or sb3-contrib missing for TQC or ARS.
    """
    if name not in ALGORITHMS:
        raise InputError(f"unknown algorithm {name!r}; use one of {', '.join(ALGORITHMS)}")
    module, cls = ALGORITHMS[name].split(":")
    try:
        return getattr(importlib.import_module(module), cls)
    except ImportError as err:
        # The package that is missing (sb3_contrib for pour-gym's ARS too), as pip names it.
        package = (err.name or module).split(".")[0].replace("_", "-")
        raise InputError(f"{name} needs the {package} package: pip install {package}") from None


def _doc(text: str) -> dict:
    """A field's one-line doc (its ``--help``)."""
    return {"doc": text}


@dataclass
class TrainConfig:
    """What a training run does (the options of ``train.py`` and ``pour-gym train``)."""

    env: str = field(default=POUR_V0, metadata=_doc("environment id"))
    algo: str = field(default="sac", metadata=_doc(f"one of {', '.join(ALGORITHMS)}"))
    recipe: str = field(
        default="",
        metadata=_doc(
            "a named variant of the algorithm's recipe (hyperparams.yaml's <algo>/<recipe>)"
        ),
    )
    objects: str = field(
        default="train", metadata=_doc("containers to train on: split, name, mesh, or a,b,c")
    )
    timesteps: int = field(default=20_000, metadata=_doc("environment steps in total"))
    seed: int = field(default=0, metadata=_doc("seed of the algorithm and the environments"))
    obs_mode: str = field(
        default="features", metadata=_doc("features, state, or a sensor: depth, rgb, points")
    )
    out: str = field(
        default="", metadata=_doc("run directory (default runs/<env>_<algo>_<objects>_...)")
    )
    n_envs: int = field(
        default=0, metadata=_doc("environments stepped side by side (0: the recipe's n_envs)")
    )
    vec: str = field(
        default="native",
        metadata=_doc(
            "how they are stepped: native (threads of this process), subproc (a worker "
            "process each) or dummy (one after the other)"
        ),
    )
    checkpoint_every: int = field(default=5_000, metadata=_doc("steps between checkpoints"))
    eval_objects: str = field(default="all", metadata=_doc("containers to evaluate on"))
    eval_episodes: int = field(default=5, metadata=_doc("evaluation episodes per container"))
    eval_seed: int = field(
        default=10_000, metadata=_doc("seed of the first evaluation episode (never trained on)")
    )
    curve_every: int = field(
        default=0, metadata=_doc("steps between learning-curve points (0: none)")
    )
    curve_episodes: int = field(default=10, metadata=_doc("episodes per learning-curve point"))
    keep_best: bool = field(
        default=False,
        metadata=_doc(
            "save as model.zip the learning-curve point with the highest success (then the "
            "lowest amount error, or the highest return), not the last step"
        ),
    )
    stochastic_eval: bool = field(
        default=False,
        metadata=_doc(
            "evaluate (and draw the learning curve with) the policy's sampled actions, seeded "
            "per episode, instead of its mean action: the policy PPO optimises"
        ),
    )
    recurve: bool = field(
        default=False,
        metadata=_doc(
            "measure the learning curve again from the checkpoints (every --curve-every "
            "steps, --curve-episodes each) before --keep-best picks among its points"
        ),
    )
    env_kwargs: dict = field(
        default_factory=dict, metadata=_doc("JSON of more environment arguments")
    )
    overrides: dict = field(
        default_factory=dict, metadata=_doc("recipe keys that replace the YAML's (--set)")
    )

    def run_dir(self) -> Path:
        """The run directory (``out``, or a name made of the run's options)."""
        if self.out:
            return Path(self.out)
        objects = self.objects.replace(",", "+").replace("/", "_")
        algo = f"{self.algo}-{self.recipe}" if self.recipe else self.algo
        name = f"{self.env.split('/')[-1]}_{algo}_{objects}_{self.obs_mode}_s{self.seed}"
        return Path("runs") / name


def config_parser(
    description: str, parser: argparse.ArgumentParser | None = None
) -> argparse.ArgumentParser:
    """A command line with one option per :class:`TrainConfig` field, plus ``--set``, ``--json``.

    Dict fields take JSON; ``--set key=value`` (repeatable, YAML values) fills ``overrides``.

    Args:
        description: the command's description.
        parser: a parser to add the options to (a subcommand's), or None for a new one.
    """
    p = parser if parser is not None else argparse.ArgumentParser(description=description)
    for f in dataclasses.fields(TrainConfig):
        flag = "--" + f.name.replace("_", "-")
        if f.name == "overrides":
            p.add_argument(
                "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                help="recipe key override (repeatable)",
            )  # fmt: skip
            continue
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if isinstance(default, bool):
            p.add_argument(flag, action="store_true", help=f.metadata["doc"])
            continue
        kind = json_object if isinstance(default, dict) else type(default)
        choices = list(ALGORITHMS) if f.name == "algo" else None
        choices = list(OBS_MODES) if f.name == "obs_mode" else choices
        choices = ["native", "subproc", "dummy"] if f.name == "vec" else choices
        p.add_argument(flag, type=kind, default=default, choices=choices, help=f.metadata["doc"])
    if parser is None or "json" not in {a.dest for a in p._actions}:
        p.add_argument("--json", action="store_true", help="print the evaluation as JSON")
    return p


def json_object(text: str) -> dict:
    """An argument that is a JSON object (argparse names the option when this raises)."""
    try:
        value = json.loads(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not JSON ({exc}): {text!r}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"a JSON object {{...}} is needed, not {text!r}")
    return value


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The :class:`TrainConfig` of parsed :func:`config_parser` arguments."""
    values = {f.name: getattr(args, f.name) for f in dataclasses.fields(TrainConfig)}
    overrides = {}
    for item in values["overrides"]:
        key, sep, value = item.partition("=")
        if not sep:
            raise InputError(f"--set takes key=value, not {item!r}")
        overrides[key] = yaml.safe_load(value)
    values["overrides"] = overrides
    return TrainConfig(**values)
