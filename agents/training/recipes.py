"""Training recipes: the entries of ``agents/hyperparams.yaml``, their keys declared.

An entry (by environment id and algorithm) mixes the algorithm's constructor arguments
with keys the training itself reads. :class:`Recipe` sorts them: every key in
:data:`RECIPE_KEYS` is the training's, declared with its meaning; every other key goes to
the algorithm, and one it does not take is refused by name. Environment wrappers and
curricula follow rl-zoo3's ``env_wrapper`` convention: a list of ``module.Class`` names,
each alone or with its keyword arguments.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib.resources import files
from typing import TYPE_CHECKING

import gymnasium as gym
import yaml

from pour_gym.agents.training.moved_modules import importable_old_paths
from pour_gym.agents.training.noise import NoiseSchedule
from pour_gym.agents.training.schedule import SCHEDULABLE, StepSchedule, SuccessSwitch
from pour_gym.errors import InputError

if TYPE_CHECKING:  # the residual module loads the envs (pybullet): only when a recipe has one
    from pour_gym.agents.policies.residual import ResidualConfig

# The keys the training reads (the rest are the algorithm's constructor arguments).
RECIPE_KEYS = {
    "n_envs": "environments stepped side by side (SubprocVecEnv workers when > 1)",
    "policy": "the SB3 policy class name (MlpPolicy)",
    "normalize": "VecNormalize's arguments (observations, rewards, clip, epsilon), or absent",
    "env_kwargs": "environment arguments (reward weights, tilt control, ...); the run's win",
    "env_wrapper": "wrappers around each training env, outermost last (rl-zoo3's convention)",
    "torch_threads": "torch's threads (1: the fluid keeps the other cores)",
    "demonstrations": "the scripted expert's episodes to start from (see DemoConfig)",
    "stochastic_eval": "evaluate and draw the curve with the policy's sampled actions (seeded)",
    "residual": "learn a correction to the scripted expert's actions (see ResidualConfig)",
    "noise_schedule": "shrink the action noise over the run's end (see NoiseSchedule)",
    "env_schedule": "an env argument changed at step counts: a curriculum (see StepSchedule)",
    "algo_schedule": "an algorithm's argument changed at step counts (see StepSchedule)",
    "switch": "when the schedules' 'switch' points take effect: a training success reached "
    "(see SuccessSwitch)",
}
RESIDUAL_WRAPPER = "pour_gym.agents.policies.residual.ExpertResidual"


@dataclass
class DemoConfig:
    """The ``demonstrations`` key of a recipe: start an off-policy learner from the expert.

    Record ``episodes`` episodes of the scripted policy (``expert``: its arguments) with
    Gaussian ``noise`` on the executed actions (one standard deviation, or one per action)
    and its clean actions as labels; keep them as a ``share`` of every replay batch;
    behaviour-clone the actor on them for ``bc_steps`` steps and keep a cloning term of
    weight ``bc_weight`` in its every update (:mod:`pour_gym.agents.training.demonstrations`). With
    ``ignore_constant`` the network is blind to the inputs the demonstrations never vary,
    and to the inputs ``hide`` names. SAC and TQC only (they have an actor).
    """

    episodes: int = 50
    share: float = 0.5
    bc_steps: int = 0
    bc_weight: float = 0.0
    noise: float | list[float] = 0.0
    expert: dict = field(default_factory=dict)
    ignore_constant: bool = False
    hide: list[str] = field(default_factory=list)

    @classmethod
    def from_recipe(cls, value: dict) -> DemoConfig:
        """From the recipe's mapping (InputError naming an unknown key)."""
        names = {f for f in cls.__dataclass_fields__}
        unknown = sorted(set(value) - names)
        if unknown:
            raise InputError(
                f"unknown demonstrations keys {unknown}; use {', '.join(sorted(names))}"
            )
        noise = value.get("noise", 0.0)
        return cls(
            episodes=int(value.get("episodes", 50)),
            share=float(value.get("share", 0.5)),
            bc_steps=int(value.get("bc_steps", 0)),
            bc_weight=float(value.get("bc_weight", 0.0)),
            noise=[float(n) for n in noise] if isinstance(noise, list) else float(noise),
            expert=dict(value.get("expert") or {}),
            ignore_constant=bool(value.get("ignore_constant", False)),
            hide=[str(name) for name in value.get("hide") or []],
        )


@dataclass
class Recipe:
    """One entry of ``hyperparams.yaml``, its keys sorted by who reads them.

    Attributes:
        hyperparameters: the algorithm's constructor arguments.
        n_envs, policy, normalize, env_kwargs, env_wrapper, torch_threads, demonstrations,
            stochastic_eval, residual, noise_schedule, env_schedule, algo_schedule, switch:
            the training's own keys (:data:`RECIPE_KEYS`).
    """

    hyperparameters: dict
    n_envs: int = 1
    policy: str = "MlpPolicy"
    normalize: dict | None = None
    env_kwargs: dict = field(default_factory=dict)
    env_wrapper: list = field(default_factory=list)
    torch_threads: int = 1
    demonstrations: DemoConfig | None = None
    stochastic_eval: bool = False
    residual: ResidualConfig | None = None
    noise_schedule: NoiseSchedule | None = None
    env_schedule: tuple[StepSchedule, ...] = ()
    algo_schedule: tuple[StepSchedule, ...] = ()
    switch: SuccessSwitch | None = None

    def wrapper(self) -> Callable[[gym.Env], gym.Env] | None:
        """A function that wraps an env in :attr:`env_wrapper`'s wrappers (None if none).

        With a :attr:`residual`, :class:`~pour_gym.agents.policies.residual.ExpertResidual` wraps
        them all (the learner acts on the expert's episodes as the curricula start them).
        It pickles by reference, so vector envs' worker processes rebuild it.
        """
        specs = wrapper_specs(self.env_wrapper)
        if self.residual is not None:
            specs.append((RESIDUAL_WRAPPER, self.residual.to_dict()))
        return functools.partial(wrap_env, specs=specs) if specs else None


def recipe_key(algo: str, variant: str = "") -> str:
    """The YAML key of an algorithm's recipe, or of a named variant of it (``ppo/residual``)."""
    return f"{algo}/{variant}" if variant else algo


def load_hyperparameters(env_id: str, algo: str, variant: str = "") -> dict:
    """The packaged recipe entry (``agents/hyperparams.yaml``) for an env and algorithm.

    Args:
        env_id: the environment id.
        algo: the algorithm's name.
        variant: a named variant of the algorithm's recipe (the entry ``<algo>/<variant>``),
            or "" for its own.
    """
    table = yaml.safe_load(files("pour_gym.agents").joinpath("hyperparams.yaml").read_text())
    name = env_id.split(":")[-1]
    if name not in table:
        raise InputError(f"no hyperparameters for {env_id!r}; known: {', '.join(table)}")
    key = recipe_key(algo, variant)
    if key not in table[name]:
        raise InputError(f"no {key!r} hyperparameters for {env_id}; known: {list(table[name])}")
    return dict(table[name][key])


def load_recipe(
    env_id: str,
    algo: str,
    algorithm_class,
    overrides: dict | None = None,
    variant: str = "",
) -> Recipe:
    """The recipe for an env and algorithm, with a run's overrides, checked.

    Args:
        env_id: the environment id.
        algo: the algorithm's name.
        algorithm_class: the SB3 algorithm class (its constructor's arguments are the
            hyperparameters it takes).
        overrides: recipe keys that replace the YAML's.
        variant: a named variant of the algorithm's recipe (``--recipe``), or "".

    Raises:
        InputError: a key neither the training's nor the algorithm's; bad wrappers or
            demonstrations.
    """
    params = {**load_hyperparameters(env_id, algo, variant), **(overrides or {})}
    own = {k: params.pop(k) for k in list(params) if k in RECIPE_KEYS}
    takes = set(inspect.signature(algorithm_class).parameters) - {"self", "policy", "env"}
    unknown = sorted(set(params) - takes)
    if unknown:
        raise InputError(
            f"unknown recipe key(s) {', '.join(unknown)} for {algorithm_class.__name__}: the "
            f"training reads {', '.join(RECIPE_KEYS)}, the algorithm takes "
            f"{', '.join(sorted(takes))}"
        )
    demos = own.get("demonstrations")
    residual = None
    if own.get("residual"):
        from pour_gym.agents.policies.residual import ResidualConfig

        residual = ResidualConfig.from_recipe(own["residual"])
    recipe = Recipe(
        hyperparameters=params,
        n_envs=int(own.get("n_envs", 1)),
        policy=str(own.get("policy", "MlpPolicy")),
        normalize=own.get("normalize"),
        env_kwargs=dict(own.get("env_kwargs") or {}),
        env_wrapper=list(_as_list(own.get("env_wrapper"))),
        torch_threads=int(own.get("torch_threads", 1)),
        demonstrations=DemoConfig.from_recipe(demos) if demos else None,
        stochastic_eval=bool(own.get("stochastic_eval", False)),
        residual=residual,
        noise_schedule=(
            NoiseSchedule.from_recipe(own["noise_schedule"]) if own.get("noise_schedule") else None
        ),
        **{
            key: StepSchedule.all_from_recipe(key, own[key]) if own.get(key) else ()
            for key in SCHEDULABLE  # env_schedule, algo_schedule
        },
        switch=SuccessSwitch.from_recipe(own["switch"]) if own.get("switch") else None,
    )
    schedules = recipe.env_schedule + recipe.algo_schedule
    if recipe.switch is not None:
        if not any(x.switched for x in schedules):
            raise InputError(
                "the recipe's switch would change nothing: give a schedule a point at it "
                "(env_schedule: {max_tilt_rate: [[0, 60], [switch, 20]]}), or drop it "
                "(--set switch=null)"
            )
        for x in schedules:
            recipe.switch.check(x)
    elif any(x.switched for x in schedules):
        raise InputError(
            "a schedule has a 'switch' point but the recipe no switch: add one (--set "
            "'switch={success: 0.3, earliest: 300000, latest: 800000}')"
        )
    for scheduled in recipe.algo_schedule:
        if scheduled.name in (overrides or {}) and scheduled.points[0][0] == 0:
            # The schedule sets it before the first rollout: the run's value would go unused.
            raise InputError(
                f"--set {scheduled.name} is replaced from the first step by the recipe's "
                f"algo_schedule {json.dumps(scheduled.to_dict())}: set the schedule instead "
                f"(--set 'algo_schedule={{{scheduled.name}: [[0, VALUE]]}}'), or drop it "
                "(--set algo_schedule=null)"
            )
    if recipe.residual is not None and recipe.demonstrations is not None:
        raise InputError("a recipe learns a residual on the expert or starts from its "
                         "demonstrations, not both")  # fmt: skip
    wrapper_specs(recipe.env_wrapper)  # refuse a bad wrapper before any work
    return recipe


# The algorithm arguments that take a schedule: rl-zoo3's "lin_<value>" there is a linear
# fall from value at the run's first step to 0 at its last.
SCHEDULED_KEYS = ("learning_rate", "clip_range")


@dataclass(frozen=True)
class LinearSchedule:
    """``start`` times the run's remaining progress (1 at the first step, 0 at the last).

    SB3 calls a schedule with its ``progress_remaining``; a class rather than a lambda so a
    saved model holding it loads without this module's closure.
    """

    start: float

    def __call__(self, progress_remaining: float) -> float:
        """The value at ``progress_remaining`` (1 at the run's first step, 0 at its last)."""
        return self.start * progress_remaining


def algorithm_arguments(hyperparameters: dict) -> dict:
    """The algorithm's constructor arguments, with ``lin_<value>`` strings made schedules.

    A recipe writes ``learning_rate: lin_0.0003`` as rl-zoo3 does (the value falls linearly
    to 0 over the run); the recipe and the run's record keep the string.

    Raises:
        InputError: a string there that is not ``lin_`` and a positive number.
    """
    out = dict(hyperparameters)
    for key in SCHEDULED_KEYS:
        value = out.get(key)
        if not isinstance(value, str):
            continue
        match = re.fullmatch(r"lin_([0-9.eE+-]+)", value)
        start = None
        if match:
            try:
                start = float(match.group(1))
            except ValueError:
                start = None
        if start is None or not start > 0:
            raise InputError(
                f"{key} is a number or lin_<positive number> (a linear fall to 0 over the "
                f"run, as in rl-zoo3), not {value!r}"
            )
        out[key] = LinearSchedule(start)
    return out


def _as_list(value) -> list:
    if value is None:
        return []
    return value if isinstance(value, list) else [value]


def wrapper_specs(entries: list) -> list[tuple[str, dict]]:
    """``env_wrapper`` entries as (``module.Class``, kwargs), each class importable.

    Raises:
        InputError: an entry that is neither a name nor a one-key mapping, or a class that
            cannot be imported.
    """
    specs = []
    for item in entries:
        if isinstance(item, str):
            name, kwargs = item, {}
        elif isinstance(item, dict) and len(item) == 1:
            name, kwargs = next(iter(item.items()))
            kwargs = dict(kwargs or {})
        else:
            raise InputError(
                f"an env_wrapper entry is 'module.Class' or {{'module.Class': {{kwargs}}}}, "
                f"not {item!r}"
            )
        _wrapper_class(name)
        specs.append((name, kwargs))
    return specs


def _wrapper_class(name: str) -> type:
    module, _, cls = name.rpartition(".")
    try:
        importable_old_paths()  # a run's config.json from before the agents were grouped
        return getattr(importlib.import_module(module), cls)
    except (ImportError, AttributeError, ValueError):
        raise InputError(f"env_wrapper names {name!r}, which cannot be imported") from None


def wrap_env(env: gym.Env, specs: list[tuple[str, dict]]) -> gym.Env:
    """``env`` wrapped in each (``module.Class``, kwargs) of ``specs``, first innermost."""
    for name, kwargs in specs:
        env = _wrapper_class(name)(env, **kwargs)
    return env
