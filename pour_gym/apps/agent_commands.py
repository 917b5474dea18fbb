"""The ``pour-gym`` subcommands of the agents: pour, evaluate, train, search and the rest.

Pour, experiment, evaluate, search, sweep, the proof of concept, demonstrations, train,
the demo and an episode's picture: each takes the parsed arguments and returns an
:data:`~pour_gym.apps.commands.Output`.

They are adapters: every one calls the library (or :mod:`pour_gym.apps`) and formats what
it returns; :mod:`pour_gym.apps.cli` builds the parser and prints.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pour_gym.apps.commands import Output
from pour_gym.errors import InputError


def cmd_pour(args: argparse.Namespace) -> Output:
    """A scripted pour between two containers, optionally as a video."""
    from tqdm import tqdm

    from pour_gym.report.video import FORMATS, write_video
    from pour_gym.sim.scenes import PourScript, scripted_pour

    if args.video and Path(args.video).suffix.lower() not in FORMATS:
        raise InputError(f"--video must end in {' or '.join(FORMATS)}, not {args.video!r}")
    if args.particles <= 0:
        raise InputError(f"--particles must be positive, not {args.particles}")
    bar = tqdm(total=100, desc="pour", file=sys.stderr, unit="%")

    def progress(done: float) -> None:
        bar.update(round(100 * done) - bar.n)

    outcome = scripted_pour(
        args.source,
        args.target,
        args.particles,
        fluid=args.fluid,
        script=PourScript(angle=args.angle),
        fps=args.fps if args.video else 0,
        progress=progress,
    )
    bar.close()
    doc = {
        "source": args.source,
        "target": args.target,
        "fluid": args.fluid,
        "particles": args.particles,
        "in_source": outcome.source,
        "in_target": outcome.target,
        "spilled": outcome.elsewhere,
    }
    if args.video:
        doc["video"] = str(write_video(outcome.frames, args.video, fps=args.fps))
    text = (
        f"{args.particles} particles from {args.source} into {args.target} ({args.fluid}): "
        f"{outcome.target} in the target, {outcome.source} left in the source, "
        f"{outcome.elsewhere} spilled"
    )
    if args.video:
        text += f"\nvideo: {doc['video']}"
    return (doc, lambda: text)


def cmd_experiment(args: argparse.Namespace) -> Output:
    """The thesis's experiments 1 and 2 with ROC curves."""
    from pour_gym.agents.thesis.experiments import run_experiment

    objects = None
    if args.objects:
        from pour_gym.assets import expand_containers

        objects = expand_containers(
            args.objects.split(",") if "," in args.objects else args.objects
        )
    doc = run_experiment(
        args.which, args.episodes, args.seed, Path(args.out), objects, address=args.address
    )
    table = doc.pop("table")
    return (doc, lambda: f"{table}\nwrote {doc['files']['png']} and results_{args.which}.json")


def cmd_evaluate(args: argparse.Namespace) -> Output:
    """Evaluate a trained model, the scripted policy or a searched one on the containers."""
    from pour_gym.agents.evaluation.evaluate import evaluate_policy, evaluation_table, load_policy
    from pour_gym.assets import expand_containers

    loaded = load_policy(args.policy, args.env, args.algo, args.actions, args.env_kwargs)
    policy, trained = loaded.policy, loaded.trained_on
    env_kwargs = {**loaded.env_kwargs, **args.env_kwargs}  # the user's win over the model's
    args.env = loaded.env_id

    def run(kwargs: dict) -> dict:
        return evaluate_policy(
            policy,
            args.env,
            expand_containers(args.objects),
            args.episodes,
            seed=args.seed,
            env_kwargs=kwargs,
            trained_on=trained,
            source_objects=expand_containers(args.source_objects) if args.source_objects else None,
            target_objects=expand_containers(args.target_objects) if args.target_objects else None,
            workers=args.workers,
        )

    if args.liquids:
        from pour_gym.agents.evaluation.evaluate import liquids_table
        from pour_gym.fluid.liquid import liquids_of

        liquids = [x.name for x in liquids_of(args.liquids)]  # unknown names fail here
        by_liquid = {name: run({**env_kwargs, "liquid": name}) for name in liquids}
        result = {"env": args.env, "policy": args.policy, "seed": args.seed,
                  "by_liquid": by_liquid}  # fmt: skip
        return (result, lambda: liquids_table(result))
    result = run(env_kwargs)
    result["policy"] = args.policy  # what a report's reference row says it was
    if args.actions:  # how a model acted, when asked: a report's row of its own
        result["actions"] = args.actions
    if args.env_kwargs:  # evaluated in other conditions than the model's own
        result["env_kwargs"] = args.env_kwargs
    return (result, lambda: evaluation_table(result))


def cmd_search(args: argparse.Namespace) -> Output:
    """CMA-ES over the scripted policy's parameters."""
    from pour_gym.agents.policies.search import search

    doc = search(
        args.objects,
        args.generations,
        args.population,
        args.episodes,
        args.seed,
        args.out,
        objective=args.objective,
        target_amount=args.target_amount,
        target_objects=args.target_objects,
        address=args.address,
        start=args.start,
        sigma=args.sigma,
        env_kwargs=args.env_kwargs,
    )
    what = "mean return" if doc["objective"] == "return" else "minus the mean error"
    text = (
        f"{what} {doc['start_score']:.3f} at the starting parameters, "
        f"{doc['best_score']:.3f} at the best found: "
        + ", ".join(f"{k}={v:.3g}" for k, v in doc["best"].items())
    )
    return (doc, lambda: text)


def cmd_sweep(args: argparse.Namespace) -> Output:
    """A grid of training runs (Ray Tune with --address)."""
    from pour_gym.agents.training.sweep import load_spec, sweep, sweep_table

    _, grid = load_spec(args.spec)
    doc = sweep(args.spec, args.out, address=args.address)
    return (doc, lambda: sweep_table(doc, list(grid)))


def cmd_poc(args: argparse.Namespace) -> Output:
    """The thesis's proof of concept, Table 6.1."""
    from pour_gym.agents.thesis.poc import poc_table, run_poc
    from pour_gym.fluid.pbf import PBFConfig

    target = args.target
    if args.target_ml is not None:
        target = round(args.target_ml * 1e-6 / PBFConfig().particle_volume)
    doc = run_poc(
        target,
        args.samples,
        args.seed,
        out=args.out,
        policy=args.policy,
        params=args.params,
        episodes=args.episodes,
    )
    return (doc, lambda: poc_table(doc))


def cmd_demonstrations(args: argparse.Namespace) -> Output:
    """The scripted expert's episodes as a Minari dataset."""
    from pour_gym.agents.training.minari_dataset import record_minari_dataset
    from pour_gym.assets import expand_containers

    env_kwargs = {"objects": list(expand_containers(args.objects)), "obs_mode": args.obs_mode}
    dataset = record_minari_dataset(
        args.minari, args.env, env_kwargs, args.episodes, seed=args.seed, noise=args.noise,
        root=Path(args.out) if args.out else None,
    )  # fmt: skip
    doc = {
        "dataset": args.minari,
        "path": str(dataset.spec.data_path),
        "episodes": int(dataset.total_episodes),
        "steps": int(dataset.total_steps),
        "env": args.env,
        "env_kwargs": env_kwargs,
    }
    root = f"MINARI_DATASETS_PATH={Path(args.out).resolve()} " if args.out else ""
    text = (
        f"wrote {doc['episodes']} episodes, {doc['steps']} steps, to {doc['path']}\n"
        f"load it: {root}python -c \"import minari; d = minari.load_dataset('{args.minari}')\""
    )
    return (doc, lambda: text)


def cmd_train(args: argparse.Namespace) -> Output:
    """Train an SB3 agent and evaluate it (the same command as ``train.py``)."""
    from pour_gym.agents.evaluation.evaluate import evaluation_table
    from pour_gym.agents.training import config_from_args, train

    result = train(config_from_args(args))
    return (result, lambda: evaluation_table(result))


def cmd_demo(args: argparse.Namespace) -> Output:
    """The main job: rebuild one thesis object from a simulated scan, then pour with it."""
    from pour_gym.apps.demo import episode_gif, run_demo

    summary = run_demo(Path(args.out), args.object)
    pour = episode_gif(Path(args.out))
    summary["pour"] = {"info": pour["info"], "video": pour["video"]}
    text = summary.pop("text") + "\n" + pour["text"]
    return (summary, lambda: text)


def cmd_episode(args: argparse.Namespace) -> Output:
    """An environment at work as a GIF: the scripted policy, or one-step episodes."""
    from pour_gym.apps.demo import episode_gif

    episode = episode_gif(
        Path(args.out), args.env, args.source, args.target, args.seed, args.target_amount,
        liquid=args.liquid,
    )  # fmt: skip
    return ({"info": episode["info"], "video": episode["video"]}, lambda: episode["text"])
