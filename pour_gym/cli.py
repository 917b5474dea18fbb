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
from pathlib import Path

from pour_gym.envs import POUR_ENV_IDS
from pour_gym.errors import ClosedContainerError, InputError, SimulationError
from pour_gym.stdio import redirect_stdout_fd
from pour_gym.texttable import text_table

Output = tuple[object, Callable[[], str]]
"""What a command returns: the JSON document and a function that formats it as text."""
POUR_ENV = "PourGym/Pour-v0"  # what evaluate runs when neither the model nor --env says


def cmd_objects(args: argparse.Namespace) -> Output:
    """List the thesis objects with their real dimensions."""
    from pour_gym.objects import SPECS

    doc = [
        {
            "name": s.name,
            "title": s.title,
            "height": s.height,
            "rim_radius": s.rim_radius,
            "volume": s.volume,
            "handle": s.handle,
        }
        for s in SPECS.values()
    ]
    if args.png:
        from pour_gym.objects import build_object
        from pour_gym.render import render_gallery

        models = [build_object(name) for name in SPECS]
        render_gallery([(m.spec.title, m.mesh, m.labels) for m in models], args.png)

    def text() -> str:
        rows = [
            [
                d["name"],
                f"{d['height'] * 100:.2f}",
                f"{d['rim_radius'] * 100:.2f}",
                f"{d['volume'] * 1e6:.0f}",
                "yes" if d["handle"] else "no",
            ]
            for d in doc
        ]
        return text_table(rows, ["name", "height cm", "rim radius cm", "volume ml", "handle"])

    return (doc, text)


def _mesh_or_object(source: str, scale: float):
    """A catalogue container's or a mesh file's mesh, and ground-truth labels (or None)."""
    from pour_gym.assets import resolve_target
    from pour_gym.fileio import validate_mesh

    name, mesh, truth = resolve_target(source, scale)
    validate_mesh(mesh, name=name)
    return mesh, (truth.labels if truth is not None else None)


def cmd_scan(args: argparse.Namespace) -> Output:
    """Scan an object or a mesh file on the simulated turntable."""
    from pour_gym.fileio import save_point_cloud
    from pour_gym.scan import ScanConfig, turntable_scan

    mesh, labels = _mesh_or_object(args.source, args.scale)
    cfg = ScanConfig(views=args.views, noise=args.noise, seed=args.seed)
    cloud = turntable_scan(mesh, labels, cfg)
    out = save_point_cloud(cloud, args.out)
    if args.png:
        from pour_gym.render import render_points

        render_points(cloud.points, args.png, title=f"scan of {args.source}")
    doc = {"out": str(out), "n_points": len(cloud.points), "config": cfg.to_dict()}
    return (doc, lambda: f"wrote {len(cloud.points)} points to {out}")


def cmd_reconstruct(args: argparse.Namespace) -> Output:
    """Reconstruct a mesh from a scan of a catalogue object or from a point cloud file."""
    from pour_gym.fileio import load_point_cloud, save_mesh
    from pour_gym.modelgen import generate_model, reconstruct_text
    from pour_gym.objects import get_spec
    from pour_gym.reconstruct import ReconstructConfig

    if (args.object is None) == (args.points is None):
        raise InputError("give either an OBJECT name or --points FILE, not both or neither")
    if args.object is not None:
        get_spec(args.object)
    cfg = ReconstructConfig(sigma=args.sigma, voxel=args.voxel, wall=args.wall, inner=args.inner)
    cloud = load_point_cloud(args.points, args.scale) if args.points else None
    result = generate_model(args.object, cloud, cfg)
    mesh_path = save_mesh(result.reconstruction.mesh, args.out)
    report = dict(result.report, mesh=str(mesh_path))
    report_path = mesh_path.with_suffix(".json")
    report_path.write_text(json.dumps(report, indent=2))
    report["report"] = str(report_path)
    if args.png:
        from pour_gym.render import render_mesh

        render_mesh(result.reconstruction.mesh, args.png, title=mesh_path.stem)
        report["png"] = str(args.png)
    return (report, lambda: reconstruct_text(report))


def cmd_measure(args: argparse.Namespace) -> Output:
    """Height, rim radius and holding volume of an upright watertight mesh."""
    from pour_gym.fileio import validate_mesh
    from pour_gym.measure import container_dimensions

    mesh, _ = _mesh_or_object(args.source, args.scale)
    validate_mesh(mesh, name=args.source, watertight=True)
    d = container_dimensions(mesh)
    if d.closed is not None:
        raise ClosedContainerError(args.source, d.closed, flag=False)
    doc = {
        "height": d.height,
        "rim_radius": d.rim_radius,
        "rim_center": list(d.rim_center),
        "volume": d.volume,
    }
    return (
        doc,
        lambda: (
            f"height {d.height * 100:.2f} cm, rim radius {d.rim_radius * 100:.2f} cm, "
            f"holds {d.volume * 1e6:.1f} ml"
        ),
    )


def cmd_report(args: argparse.Namespace) -> Output:
    """Tables beside the thesis's: reconstruction (chapter 3) or warping (chapter 4)."""
    from tqdm import tqdm

    from pour_gym.modelgen import generate_model, reconstruction_table
    from pour_gym.objects import OBJECT_NAMES

    if args.what == "generalisation":
        from pour_gym.agents.study import study_report

        if not args.runs or not args.out:
            raise InputError("report generalisation needs --runs DIR and --out DIR")
        summary = study_report(args.runs, args.out)
        return (summary, lambda: (Path(args.out) / "report.md").read_text())
    if args.what == "warping":
        from pour_gym.assets import label_container, warping_tables

        warp = {}
        for name in tqdm(OBJECT_NAMES, desc="label from red_cup", file=sys.stderr):
            warp[name] = {m: label_container(name, "red_cup", m).meta for m in ("thesis", "best")}
        return (warp, lambda: warping_tables(warp))
    reports = {
        name: generate_model(name).report
        for name in tqdm(OBJECT_NAMES, desc="scan + reconstruct", file=sys.stderr)
    }
    return (reports, lambda: reconstruction_table(reports))


def cmd_label(args: argparse.Namespace) -> Output:
    """Label a container by warping a labelled source onto it; write the asset."""
    from pour_gym.assets import label_container, write_asset

    asset = label_container(
        args.target, args.source, args.method, args.scale, allow_closed=args.allow_closed
    )
    out = write_asset(asset, args.out)
    doc = dict(asset.meta, out=str(out))

    def text() -> str:
        lines = [f"labelled {asset.name} from {args.source} ({args.method}) into {out}"]
        g = asset.geometry
        lines.append(
            f"  height {g.height * 100:.2f} cm, rim radius {g.rim_radius * 100:.2f} cm, "
            f"cavity {g.cavity_volume * 1e6:.0f} ml (convex hull {g.container_volume * 1e6:.0f} ml)"
        )
        if "iou" in asset.meta:
            iou = ", ".join(f"{k} {v:.3f}" for k, v in asset.meta["iou"].items() if v is not None)
            lines.append(f"  IoU against ground truth: {iou}")
        return "\n".join(lines)

    return (doc, text)


def cmd_build_assets(args: argparse.Namespace) -> Output:
    """Label every catalogue container from the source and write the packaged assets."""
    from tqdm import tqdm

    from pour_gym.assets import CATALOGUE, asset_root, label_container, write_asset

    root = Path(args.out) if args.out else asset_root()
    done = {}
    for name in tqdm(CATALOGUE, desc="build assets", file=sys.stderr):
        asset = label_container(name, args.source, args.method)
        done[name] = str(write_asset(asset, root / name))
    return (done, lambda: f"wrote {len(done)} assets under {root}")


def cmd_bench(args: argparse.Namespace) -> Output:
    """Benchmarks."""
    from pour_gym.bench import (
        bench_envs,
        bench_fluid,
        bench_label,
        bench_ray,
        bench_reconstruct,
        envs_table,
        fluid_table,
        label_table,
        ray_table,
        reconstruct_table,
    )

    if args.what == "fluid":
        sizes = [int(s) for s in (args.sizes or "300,1000,2000,4000,16000").split(",")]
        bullet = [int(s) for s in args.bullet_sizes.split(",") if s]
        result = bench_fluid(sizes, bullet, repeats=args.repeats)
        doc = {k: result[k] for k in ("pbf", "bullet", "ratio_at_2000", "realtime")}
        return (doc, lambda: fluid_table(result))
    if args.what == "envs":
        result = bench_envs(repeats=args.repeats)
        return (result, lambda: envs_table(result))
    if args.what == "ray":
        result = bench_ray(repeats=args.repeats)
        return (result, lambda: ray_table(result))
    if args.what == "label":
        sizes = [int(s) for s in (args.sizes or "5000,10000,20000,40000").split(",")]
        rows = bench_label(sizes, repeats=args.repeats)
        return ({"label": rows}, lambda: label_table(rows))
    sizes = [int(s) for s in (args.sizes or "5000,10000,25000,50000,100000").split(",")]
    rows = bench_reconstruct(sizes, repeats=args.repeats)
    return ({"reconstruct": rows}, lambda: reconstruct_table(rows))


def cmd_soak(args: argparse.Namespace) -> Output:
    """Random actions over containers: exceptions, false endings, lost particles, walls."""
    from pour_gym.assets import expand_containers
    from pour_gym.soak import soak, soak_table

    objects = list(expand_containers(args.objects)) if args.objects else None
    if args.user_meshes or objects is None:
        from pour_gym.cache import cache_dir
        from pour_gym.soak import user_meshes

        if objects is not None:
            objects += user_meshes(cache_dir("soak"))
    if args.episodes < 1 or args.steps < 1:
        raise InputError("--episodes and --steps must be at least 1")
    doc = soak(args.env, objects, args.episodes, args.steps, args.seed)
    return (doc, lambda: soak_table(doc))


def cmd_pour(args: argparse.Namespace) -> Output:
    """A scripted pour between two containers, optionally as a video."""
    from tqdm import tqdm

    from pour_gym.sim.scenes import PourScript, scripted_pour
    from pour_gym.video import FORMATS, write_video

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
    from pour_gym.agents.experiments import run_experiment

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
    from pour_gym.agents.evaluate import evaluate_policy, evaluation_table
    from pour_gym.agents.rollout import sb3_policy
    from pour_gym.assets import expand_containers

    env_kwargs: dict = {}
    trained: list[str] = []
    if args.policy == "scripted" or args.policy.endswith(".json"):
        args.env = args.env or POUR_ENV
        from pour_gym.agents.scripted import ScriptedPourPolicy
        from pour_gym.agents.search import load_search

        if args.env not in POUR_ENV_IDS:
            raise InputError(
                f"the scripted policy pours: use --env with one of {', '.join(POUR_ENV_IDS)}"
            )
        if args.policy == "scripted":
            policy = ScriptedPourPolicy()
        else:  # the best of a policy search, trained on the containers it searched on
            found = load_search(args.policy)
            policy = ScriptedPourPolicy(**found["best"])
            trained = found.get("sources", [])
    else:
        from pour_gym.agents.training import load_run

        run = load_run(args.policy, args.algo)
        args.env = args.env or run.config.get("env") or POUR_ENV
        if run.config.get("env") and run.config["env"] != args.env:
            raise InputError(f"the model was trained on {run.config['env']}, not {args.env}")
        policy = sb3_policy(run)
        env_kwargs = run.env_kwargs()
        trained = run.trained_on()
    result = evaluate_policy(
        policy,
        args.env,
        expand_containers(args.objects),
        args.episodes,
        seed=args.seed,
        env_kwargs=env_kwargs,
        trained_on=trained,
        source_objects=expand_containers(args.source_objects) if args.source_objects else None,
        target_objects=expand_containers(args.target_objects) if args.target_objects else None,
    )
    return (result, lambda: evaluation_table(result))


def cmd_search(args: argparse.Namespace) -> Output:
    """CMA-ES over the scripted policy's parameters."""
    from pour_gym.agents.search import search

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
    from pour_gym.agents.sweep import load_spec, sweep, sweep_table

    _, grid = load_spec(args.spec)
    doc = sweep(args.spec, args.out, address=args.address)
    return (doc, lambda: sweep_table(doc, list(grid)))


def cmd_poc(args: argparse.Namespace) -> Output:
    """The thesis's proof of concept, Table 6.1."""
    from pour_gym.agents.poc import poc_table, run_poc
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


def cmd_demo(args: argparse.Namespace) -> Output:
    """The main job: rebuild one thesis object from a simulated scan."""
    from pour_gym.demo import pour_episode, run_demo

    summary = run_demo(Path(args.out), args.object)
    pour = pour_episode(Path(args.out))
    summary["pour"] = {"info": pour["info"], "video": pour["video"]}
    text = summary.pop("text") + "\n" + pour["text"]
    return (summary, lambda: text)


def cmd_episode(args: argparse.Namespace) -> Output:
    """One episode of the scripted policy in a pouring task, as a GIF."""
    from pour_gym.demo import pour_episode

    episode = pour_episode(
        Path(args.out), args.source, args.target, args.seed, args.target_amount, args.env
    )
    return ({"info": episode["info"], "video": episode["video"]}, lambda: episode["text"])


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

    p = add("objects", cmd_objects, "list the thesis objects and their real dimensions")
    p.add_argument("--png", help="also draw all of them, labelled, into this PNG")

    p = add("scan", cmd_scan, "simulated turntable depth scan of an object or mesh file")
    p.add_argument("source", help="catalogue container or mesh file (OBJ/STL/PLY/GLB)")
    p.add_argument("--out", required=True, help="output cloud (.ply, .pcd, .xyz, .npy)")
    p.add_argument("--views", type=int, default=24, help="turntable steps per revolution")
    p.add_argument("--noise", type=float, default=0.0005, help="depth noise std, m")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scale", type=float, default=1.0, help="mesh units to m (0.001 for mm)")
    p.add_argument("--png", help="also write a picture of the cloud")

    p = add("reconstruct", cmd_reconstruct, "point cloud -> implicit surface -> mesh (ch. 3)")
    p.add_argument("object", nargs="?", help="thesis object to scan and rebuild")
    p.add_argument("--points", help="point cloud file instead (.ply, .pcd, .xyz, .npy)")
    p.add_argument("--out", required=True, help="output mesh (.obj, .stl, .ply, .glb)")
    p.add_argument("--inner", choices=["thesis", "offset"], default="offset")
    p.add_argument("--wall", type=float, default=0.004, help="wall thickness, m (offset)")
    p.add_argument("--sigma", type=float, default=0.01, help="Gaussian kernel width, m")
    p.add_argument("--voxel", type=float, default=0.00125, help="marching-cubes voxel, m")
    p.add_argument("--scale", type=float, default=1.0, help="cloud units to m (0.001 for mm)")
    p.add_argument("--png", help="also write a picture of the mesh")

    p = add("measure", cmd_measure, "height, rim radius and holding volume of a mesh")
    p.add_argument("source", help="thesis object name or watertight mesh file, upright")
    p.add_argument("--scale", type=float, default=1.0, help="mesh units to m")

    p = add("report", cmd_report, "tables beside the thesis's (scan + reconstruct all objects)")
    p.add_argument("what", choices=["reconstruction", "warping", "generalisation"])
    p.add_argument("--runs", help="generalisation: folder of train.py runs")
    p.add_argument("--out", help="generalisation: folder for report.md and plots")

    p = add("label", cmd_label, "label a container's parts by warping a labelled source (ch. 4)")
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

    p = add("build-assets", cmd_build_assets, "label every catalogue container into assets/")
    p.add_argument("--source", default="red_cup")
    p.add_argument("--method", choices=["best", "thesis"], default="best")
    p.add_argument("--out", help="folder (default: the packaged assets folder)")

    p = add("bench", cmd_bench, "benchmarks (medians of repeated runs)")
    p.add_argument("what", choices=["reconstruct", "label", "fluid", "envs", "ray"])
    p.add_argument("--sizes", help="comma-separated sizes (points, target vertices or particles)")
    p.add_argument(
        "--bullet-sizes",
        default="300,2000",
        help="fluid: particle counts for the rigid-sphere backend ('' for none)",
    )
    p.add_argument("--repeats", type=int, default=3)

    p = add("soak", cmd_soak, "random actions over containers: what must never happen")
    p.add_argument("--env", default="PourGym/Pour-v0")
    p.add_argument(
        "--objects", help="containers (default: the catalogue and two meshes like users')"
    )
    p.add_argument("--user-meshes", action="store_true", help="add the two user-like meshes")
    p.add_argument("--episodes", type=int, default=20, help="episodes per container")
    p.add_argument("--steps", type=int, default=250, help="most steps per episode")
    p.add_argument("--seed", type=int, default=0)

    p = add("pour", cmd_pour, "scripted pour from a held container into another (fluid demo)")
    p.add_argument("--source", default="red_cup", help="held container (catalogue or asset dir)")
    p.add_argument("--target", default="broad_cup", help="container on the table")
    p.add_argument("--particles", type=int, default=1000, help="fluid in the source")
    p.add_argument("--fluid", choices=["pbf", "bullet"], default="pbf")
    p.add_argument("--angle", type=float, default=110.0, help="largest tilt, degrees")
    p.add_argument("--video", help="write the pour as .gif (or .mp4 with imageio-ffmpeg)")
    p.add_argument("--fps", type=int, default=20)

    p = add("experiment", cmd_experiment, "thesis experiments 1 (drop) and 2 (tilt), ROC curves")
    p.add_argument("which", choices=["drop", "tilt"])
    p.add_argument("--episodes", type=int, default=400, help="episodes per object")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="experiments", help="output folder")
    p.add_argument("--objects", help="split or comma-separated containers (default: all nine)")
    add_address(p, "collect the episodes as Ray tasks")

    p = add("evaluate", cmd_evaluate, "success, amount error and spill per container")
    p.add_argument(
        "policy",
        help="an SB3 model.zip from train.py, the name of a shipped model (e.g. "
        "pour-v0-red-cup-features), 'scripted', or a search.json",
    )
    p.add_argument("--env", help="environment id (default: the model's, or Pour-v0)")
    p.add_argument("--objects", default="all", help="split or comma-separated containers")
    p.add_argument("--episodes", type=int, default=5, help="episodes per container")
    p.add_argument("--seed", type=int, default=10_000, help="seed of the first episode")
    p.add_argument("--source-objects", help="Pour-v0: sources of a source x target matrix of rows")
    p.add_argument("--target-objects", help="Pour-v0: targets of the matrix (default: --objects)")
    p.add_argument("--algo", help="algorithm, if the model has no config.json beside it")

    p = add("search", cmd_search, "CMA-ES policy search over the scripted policy (Pour-v0)")
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
    add_address(p, "evaluate each generation's candidates as Ray tasks")

    p = add("sweep", cmd_sweep, "a grid of train.py runs (Ray Tune trials with --address)")
    p.add_argument("spec", help="YAML: TrainConfig fields and a grid: of fields to vary")
    p.add_argument("--out", required=True, help="folder of the trials' run directories")
    add_address(p, "run the trials on Ray Tune")

    p = add("poc", cmd_poc, "the thesis's proof-of-concept pouring policy (Table 6.1)")
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

    p = add("episode", cmd_episode, "one scripted episode of a pouring task as a GIF")
    p.add_argument("--env", default=POUR_ENV, choices=POUR_ENV_IDS)
    p.add_argument("--source", default="red_cup", help="held container")
    p.add_argument("--target", default="broad_cup", help="container on the table")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--target-amount", type=int, help="particles to pour (default: random)")
    p.add_argument("--out", default="docs", help="output folder")

    p = add("demo", cmd_demo, "rebuild a thesis object from a scan, then pour with it (GIF)")
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
