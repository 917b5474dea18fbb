"""The ``pour-gym`` command line.

Every subcommand with ``--json`` prints exactly one JSON document on stdout and nothing
else: while it works, anything written to the process's stdout (by C libraries too) goes
to stderr. Tables and progress go to stderr, or to stdout without ``--json``. Bad input
ends with a one-line message and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable

from pour_gym.apps import agent_commands, commands
from pour_gym.envs import POUR_V0, POUR_V1
from pour_gym.errors import InputError, SimulationError
from pour_gym.io.stdio import redirect_stdout_fd


def add_address(p: argparse.ArgumentParser, what: str) -> None:
    """The ``--address`` option of the commands that can run on Ray."""
    p.add_argument(
        "--address",
        help=f"{what}: 'local' (a Ray instance on this machine), 'auto' (the cluster this "
        "machine joined) or HOST:PORT (a head node); needs pip install 'pour-gym[ray]'",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pour-gym``."""
    from pour_gym import __version__
    from pour_gym.agents.training.config import config_parser, json_object

    parser = argparse.ArgumentParser(
        prog="pour-gym",
        description="Learning to pour with warped features: model generation, warping, "
        "fluid, environments.",
    )
    parser.add_argument("--version", action="version", version=f"pour-gym {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    def add(name: str, func: Callable, help_: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=help_)
        p.add_argument("--json", action="store_true", help="print one JSON document")
        p.set_defaults(func=func)
        return p

    p = add(
        "objects",
        commands.cmd_objects,
        "list the thesis objects (or a procedural family) and their dimensions",
    )
    p.add_argument("--png", help="also draw them, labelled, into this PNG")
    p.add_argument(
        "--procedural",
        metavar="FAMILY",
        help="a procedural family instead: procedural:train, procedural:test or "
        "procedural:N@SEED (each member built and checked watertight)",
    )
    p.add_argument(
        "--sheet", type=int, default=50, help="--procedural --png: draw the first N members"
    )
    p.add_argument(
        "--out", help="--procedural: write each member as a labelled asset (warped) under DIR"
    )

    p = add("scan", commands.cmd_scan, "simulated turntable depth scan of an object or mesh file")
    p.add_argument("source", help="catalogue container or mesh file (OBJ/STL/PLY/GLB)")
    p.add_argument("--out", required=True, help="output cloud (.ply, .pcd, .xyz, .npy)")
    p.add_argument("--views", type=int, default=24, help="turntable steps per revolution")
    p.add_argument("--noise", type=float, default=0.0005, help="depth noise std, m")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scale", type=float, default=1.0, help="mesh units to m (0.001 for mm)")
    p.add_argument("--png", help="also write a picture of the cloud")

    p = add(
        "reconstruct", commands.cmd_reconstruct, "point cloud -> implicit surface -> mesh (ch. 3)"
    )
    p.add_argument("object", nargs="?", help="thesis object to scan and rebuild")
    p.add_argument("--points", help="point cloud file instead (.ply, .pcd, .xyz, .npy)")
    p.add_argument("--out", required=True, help="output mesh (.obj, .stl, .ply, .glb)")
    p.add_argument("--inner", choices=["thesis", "offset"], default="offset")
    p.add_argument("--wall", type=float, default=0.004, help="wall thickness, m (offset)")
    p.add_argument("--sigma", type=float, default=0.01, help="Gaussian kernel width, m")
    p.add_argument("--voxel", type=float, default=0.00125, help="marching-cubes voxel, m")
    p.add_argument("--scale", type=float, default=1.0, help="cloud units to m (0.001 for mm)")
    p.add_argument("--png", help="also write a picture of the mesh")

    p = add("measure", commands.cmd_measure, "height, rim radius and holding volume of a mesh")
    p.add_argument("source", help="thesis object name or watertight mesh file, upright")
    p.add_argument("--scale", type=float, default=1.0, help="mesh units to m")

    p = add(
        "report",
        commands.cmd_report,
        "reports: reconstruction and warping beside the thesis's tables, generalisation, "
        "baselines over seeds",
    )
    p.add_argument(
        "what", choices=["reconstruction", "warping", "generalisation", "baselines", "sensors"]
    )
    p.add_argument(
        "--runs", nargs="+", default=[],
        help="generalisation, baselines: train.py run directories or folders of them",
    )  # fmt: skip
    p.add_argument(
        "--reference", nargs="+", default=[],
        help="baselines: evaluations of the scripted expert and of the random policy "
        "(pour-gym evaluate scripted|random --json), each added as a reference row; with "
        "both, the rows' normalised returns and probability of improvement",
    )  # fmt: skip
    p.add_argument(
        "--out", help="generalisation: folder for report.md and plots; sensors: for the PNGs"
    )
    p.add_argument(
        "--family",
        help="warping, generalisation: over a procedural family (procedural:test), results "
        "per shape-parameter bucket",
    )
    p.add_argument(
        "--policies",
        default="scripted,pour-v0-red-cup-features",
        help="generalisation --family: comma-separated policies (scripted, shipped models, "
        "model files)",
    )
    p.add_argument(
        "--episodes", type=int, default=2, help="generalisation --family: episodes per container"
    )
    p.add_argument(
        "--perception",
        default="true",
        help="generalisation --family: the features' geometry, comma-separated: true (the "
        "labelled mesh), scan (scanned, reconstructed, warped: as a robot perceives it)",
    )
    p.add_argument(
        "--scan-seed", type=int, default=0, help="generalisation --family: the scans' noise seed"
    )
    p.add_argument(
        "--seed", type=int, default=60_000, help="generalisation --family: first episode's seed"
    )
    p.add_argument(
        "--liquids",
        help="generalisation --family: comma-separated liquids (water,milk,oil,syrup,honey): "
        "each policy pours every member with each, the same episodes; a column per liquid",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help="generalisation --family: members evaluated at once, in threads (the same "
        "results for any number; not with sampled actions)",
    )

    p = add(
        "label",
        commands.cmd_label,
        "label a container's parts by warping a labelled source (ch. 4)",
    )
    p.add_argument("target", help="catalogue container or mesh file (any pose, any size in m)")
    p.add_argument("--source", default="red_cup", help="labelled thesis object to warp from")
    p.add_argument("--out", required=True, help="asset directory to write")
    p.add_argument("--method", choices=["best", "thesis"], default="best")
    p.add_argument("--scale", type=float, default=1.0, help="mesh units to m")
    p.add_argument(
        "--allow-closed",
        action="store_true",
        help="label a container with no opening (a capped scan) anyway; envs refuse it",
    )

    p = add(
        "build-assets",
        commands.cmd_build_assets,
        "label every catalogue container into assets/, or (--objects) make any containers "
        "ready ahead of a run: labelled and their fields cached, in parallel",
    )
    p.add_argument("--source", default="red_cup")
    p.add_argument("--method", choices=["best", "thesis"], default="best")
    p.add_argument("--out", help="folder (default: the packaged assets folder)")
    p.add_argument(
        "--objects",
        help="containers to make ready in the user cache (a family such as procedural:train, "
        "a split, names, files) instead of the packaged catalogue",
    )
    p.add_argument("--jobs", type=int, help="--objects: processes (default: one per core)")
    p.add_argument(
        "--perceive", action="store_true", help="--objects: also as perception='scan' sees them"
    )
    p.add_argument("--scan-seed", type=int, default=0, help="--perceive: the scans' noise seed")

    p = add("bench", commands.cmd_bench, "benchmarks (medians of repeated runs)")
    p.add_argument(
        "what",
        choices=[
            "reconstruct", "label", "fluid", "accuracy", "viscosity", "flows", "efflux",
            "liquids", "envs", "ray", "coldstart",
        ],
        help="accuracy is the fluid's against hydrostatics (not a timing); viscosity the "
        "fluid's measured against the liquids'; flows efflux, a dam break and the liquids' "
        "pours; efflux water's efflux by particle spacing (--sizes: spacings, mm) and the "
        "vessel's scale (--scales); liquids "
        "a step's cost by liquid; coldstart the seconds a new process takes to its first step",
    )  # fmt: skip
    p.add_argument("--out", help="flows: a folder for the figure (flows.png)")
    p.add_argument(
        "--spacing",
        type=float,
        default=0.005,
        help="accuracy, viscosity: the particles' spacing, m (the envs' spacing=)",
    )
    p.add_argument(
        "--part",
        choices=["calibration", "liquids", "both"],
        default="both",
        help="viscosity: the calibration table, the liquids through the package's, or both",
    )
    p.add_argument("--sizes", help="comma-separated sizes (points, target vertices or particles)")
    p.add_argument(
        "--scales",
        default="1",
        help="efflux: comma-separated scales of the vessel, hole and column (2: twice as large)",
    )
    p.add_argument(
        "--bullet-sizes",
        default="300,2000",
        help="fluid: particle counts for the rigid-sphere backend ('' for none)",
    )
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--envs", help="coldstart: comma-separated env ids (default: every one)")
    p.add_argument(
        "--sections",
        help="envs: comma-separated parts to run, of pour, vec, native, memory, family, rows, "
        "sensors (default: all but family, a half-hour memory probe)",
    )

    p = add("soak", commands.cmd_soak, "random actions over containers: what must never happen")
    p.add_argument("--env", default=POUR_V0)
    p.add_argument(
        "--objects", help="containers (default: the catalogue and two meshes like users')"
    )
    p.add_argument("--user-meshes", action="store_true", help="add the two user-like meshes")
    p.add_argument("--episodes", type=int, default=20, help="episodes per container")
    p.add_argument("--steps", type=int, default=250, help="most steps per episode")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--liquids",
        help="comma-separated liquids (water,milk,oil,syrup,honey): each container with "
        "each, and a row per liquid",
    )

    p = add(
        "pour",
        agent_commands.cmd_pour,
        "scripted pour from a held container into another (fluid demo)",
    )
    p.add_argument("--source", default="red_cup", help="held container (catalogue or asset dir)")
    p.add_argument("--target", default="broad_cup", help="container on the table")
    p.add_argument("--particles", type=int, default=1000, help="fluid in the source")
    p.add_argument("--fluid", choices=["pbf", "bullet"], default="pbf")
    p.add_argument("--angle", type=float, default=110.0, help="largest tilt, degrees")
    p.add_argument("--video", help="write the pour as .gif (or .mp4 with imageio-ffmpeg)")
    p.add_argument("--fps", type=int, default=20)

    p = add(
        "experiment",
        agent_commands.cmd_experiment,
        "thesis experiments 1 (drop) and 2 (tilt), ROC curves",
    )
    p.add_argument("which", choices=["drop", "tilt"])
    p.add_argument("--episodes", type=int, default=400, help="episodes per object")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="experiments", help="output folder")
    p.add_argument("--objects", help="split or comma-separated containers (default: all nine)")
    add_address(p, "collect the episodes as Ray tasks")

    p = add(
        "evaluate", agent_commands.cmd_evaluate, "success, amount error and spill per container"
    )
    p.add_argument(
        "policy",
        help="an SB3 model.zip from train.py (or the run folder holding it), the name of a "
        "shipped model (e.g. pour-v0-red-cup-features), 'scripted', 'random' (uniform "
        "actions, seeded per episode), or a search.json",
    )
    p.add_argument("--env", help="environment id (default: the model's, or Pour-v0)")
    p.add_argument("--objects", default="all", help="split or comma-separated containers")
    p.add_argument("--episodes", type=int, default=5, help="episodes per container")
    p.add_argument("--seed", type=int, default=10_000, help="seed of the first episode")
    p.add_argument("--source-objects", help="Pour-v0: sources of a source x target matrix of rows")
    p.add_argument("--target-objects", help="Pour-v0: targets of the matrix (default: --objects)")
    p.add_argument("--algo", help="algorithm, if the model has no config.json beside it")
    p.add_argument(
        "--actions",
        choices=("mean", "sampled"),
        help="a model's mean action or its sampled ones (seeded per episode); default: as "
        "its run scored it (stochastic_eval in its config.json)",
    )
    p.add_argument(
        "--env-kwargs",
        type=json_object,
        default={},
        help="JSON of more environment arguments, over the model's own (its config.json's), "
        'e.g. \'{"spill_weight": 10}\' or \'{"holder": "panda"}\'',
    )
    p.add_argument(
        "--liquids",
        help="comma-separated liquids (water,milk,oil,syrup,honey): every container with "
        "each, the same episodes, and a row per liquid",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help="containers evaluated at once, in threads of one process (the same results for "
        "any number; 2 uses both cores of a 2-core machine); not with sampled actions",
    )

    p = add(
        "search",
        agent_commands.cmd_search,
        "CMA-ES policy search over the scripted policy (Pour-v0)",
    )
    p.add_argument("--objects", default="train")
    p.add_argument("--generations", type=int, default=6)
    p.add_argument("--population", type=int, default=6)
    p.add_argument("--episodes", type=int, default=3, help="episodes per candidate")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", help="folder for search.json")
    p.add_argument(
        "--objective",
        choices=("return", "error"),
        default="return",
        help="maximise the return, or minimise |poured - target| (particles)",
    )
    p.add_argument("--target-amount", type=int, help="pour this many particles every episode")
    p.add_argument("--target-objects", help="containers to pour into (default: --objects)")
    p.add_argument(
        "--start",
        choices=("search", "expert"),
        default="search",
        help="start from the search's own point, or from the scripted expert's defaults",
    )
    p.add_argument("--sigma", type=float, default=0.2, help="CMA-ES's first step in the unit cube")
    p.add_argument(
        "--env-kwargs",
        type=json_object,
        default={},
        help="JSON of Pour-v0 arguments, e.g. reward weights: '{\"progress_weight\": 20}'",
    )
    add_address(p, "evaluate each generation's candidates as Ray tasks")

    p = add(
        "sweep",
        agent_commands.cmd_sweep,
        "a grid of train.py runs (Ray Tune trials with --address)",
    )
    p.add_argument("spec", help="YAML: TrainConfig fields and a grid: of fields to vary")
    p.add_argument("--out", required=True, help="folder of the trials' run directories")
    add_address(p, "run the trials on Ray Tune")

    p = add(
        "poc", agent_commands.cmd_poc, "the thesis's proof-of-concept pouring policy (Table 6.1)"
    )
    p.add_argument("--target", type=int, default=20, help="particles to pour (0.125 ml each)")
    p.add_argument("--samples", type=int, default=60, help="red-cup episodes to learn from")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--target-ml", type=float, help="the target in ml instead (default fluid)")
    p.add_argument(
        "--policy",
        choices=("thesis", "closed-loop"),
        default="thesis",
        help="thesis: open-loop tilt and hold; closed-loop: timed by the stream",
    )
    p.add_argument("--params", help="search.json of a policy search (closed-loop policy)")
    p.add_argument("--episodes", type=int, default=1, help="pours per cup (seeds seed, ...)")
    p.add_argument("--out", help="folder for poc_<policy>_<target>.json")

    p = add("episode", agent_commands.cmd_episode, "an environment at work as a GIF (<env>.gif)")
    p.add_argument("--env", default=POUR_V0, help="environment id")
    p.add_argument("--source", default="red_cup", help="held container (or the container)")
    p.add_argument("--target", default="broad_cup", help="container on the table")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--target-amount", type=int, help="particles to pour (default: random)")
    p.add_argument("--out", default="docs/environments", help="output folder")
    p.add_argument("--liquid", help="a liquid's preset (water, milk, oil, syrup, honey)")

    p = add(
        "demonstrations",
        agent_commands.cmd_demonstrations,
        "record the scripted expert's episodes as a Minari dataset (offline RL)",
    )
    p.add_argument(
        "--minari", required=True, metavar="NAME",
        help="dataset id, [namespace/]name-vN (e.g. pourgym/red-cup-expert-v0)",
    )  # fmt: skip
    p.add_argument("--env", default=POUR_V1, help="a pouring environment id")
    p.add_argument("--objects", default="red_cup", help="split or comma-separated containers")
    p.add_argument("--episodes", type=int, default=50)
    p.add_argument("--seed", type=int, default=0, help="episode k is reset with seed + k")
    p.add_argument("--obs-mode", choices=["features", "state"], default="features")
    p.add_argument("--noise", type=float, default=0.0, help="action noise std (0: the expert's)")
    p.add_argument("--out", help="Minari's datasets folder (default: $MINARI_DATASETS_PATH or "
                   "~/.minari/datasets)")  # fmt: skip

    p = add("train", agent_commands.cmd_train, "train an SB3 agent and evaluate it (as train.py)")
    config_parser(p.description, parser=p)

    p = add(
        "demo",
        agent_commands.cmd_demo,
        "rebuild a thesis object from a scan, then pour with it (GIF)",
    )
    p.add_argument("--out", default="demo_out")
    p.add_argument("--object", default="red_cup")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.json:
            with redirect_stdout_fd(2):
                doc, _ = args.func(args)
            print(json.dumps(doc, indent=2))
        else:
            _, text = args.func(args)
            print(text())
    except InputError as exc:
        print(f"pour-gym {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (SimulationError, FloatingPointError) as exc:
        print(f"pour-gym {args.command}: simulation failed: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader (head, jq -e ...) closed the pipe: not an error
        sys.stderr.close()
        return 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
