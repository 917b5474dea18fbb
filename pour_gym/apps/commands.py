"""The ``pour-gym`` subcommands of the data side: objects, scans, meshes, labels, assets.

Objects, scans, reconstructions, measures, reports, labels, assets, benchmarks and the
soak: each takes the parsed arguments and returns an :data:`Output`.

The agents' commands (pour, evaluate, train, search, ...) are in
:mod:`pour_gym.apps.agent_commands`.

They are adapters: every one calls the library (or :mod:`pour_gym.apps`) and formats what
it returns; :mod:`pour_gym.apps.cli` builds the parser and prints.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

from pour_gym.errors import ClosedContainerError, InputError
from pour_gym.report.tables import text_table

Output = tuple[object, Callable[[], str]]
"""What a command returns: the JSON document and a function that formats it as text."""


def cmd_objects(args: argparse.Namespace) -> Output:
    """List the thesis objects with their real dimensions (or a procedural family)."""
    from pour_gym.objects import SPECS

    if args.procedural:
        return _procedural_family(args)
    if args.out:
        raise InputError("--out writes a procedural family's assets: add --procedural FAMILY")

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
        from pour_gym.report.pictures import render_gallery

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


def _procedural_family(args: argparse.Namespace) -> Output:
    """Build every member of a procedural family; draw a sheet, write assets if asked."""
    from tqdm import tqdm

    from pour_gym.objects.procedural import build_member, family_members

    names = family_members(args.procedural)
    doc, models = [], {}
    for name in tqdm(names, desc=f"build {args.procedural}", file=sys.stderr):
        model = build_member(name)
        s = model.spec
        doc.append(
            {
                **s.to_dict(),
                "volume": model.cavity_volume,
                "watertight": bool(model.mesh.is_watertight),
                "vertices": len(model.mesh.vertices),
            }
        )
        if len(models) < args.sheet:
            models[name] = model
    if args.png:
        from pour_gym.report.pictures import render_gallery

        panels = [
            (f"{n.split('#')[1]} {m.spec.profile}", m.mesh, m.labels) for n, m in models.items()
        ]
        render_gallery(panels, args.png, columns=10, dpi=50)
    if args.out:
        from pour_gym.assets import resolve_asset, write_asset

        # The environments' own labelling, cached: a member labelled once is not warped again.
        for name in tqdm(names, desc="label and write", file=sys.stderr):
            stem = name.removeprefix("procedural:").replace("#", "_").replace("@", "_")
            write_asset(resolve_asset(name), Path(args.out) / stem, picture=False)

    def text() -> str:
        rows = [
            [
                d["name"],
                d["profile"],
                d["cross_section"],
                d["lip"],
                "yes" if d["handle"] else "no",
                f"{d['height'] * 100:.1f}",
                f"{d['rim_radius'] * 100:.1f}",
                f"{d['volume'] * 1e6:.0f}",
                "yes" if d["watertight"] else "NO",
            ]
            for d in doc
        ]
        header = ["name", "profile", "section", "lip", "handle", "height cm", "rim cm",
                  "volume ml", "watertight"]  # fmt: skip
        return text_table(rows, header)

    return (doc, text)


def _mesh_or_object(source: str, scale: float):
    """A catalogue container's or a mesh file's mesh, and ground-truth labels (or None)."""
    from pour_gym.assets import resolve_target
    from pour_gym.mesh.fileio import validate_mesh

    name, mesh, truth = resolve_target(source, scale)
    validate_mesh(mesh, name=name)
    return mesh, (truth.labels if truth is not None else None)


def cmd_scan(args: argparse.Namespace) -> Output:
    """Scan an object or a mesh file on the simulated turntable."""
    from pour_gym.mesh.fileio import save_point_cloud
    from pour_gym.mesh.scan import ScanConfig, turntable_scan

    mesh, labels = _mesh_or_object(args.source, args.scale)
    cfg = ScanConfig(views=args.views, noise=args.noise, seed=args.seed)
    cloud = turntable_scan(mesh, labels, cfg)
    out = save_point_cloud(cloud, args.out)
    if args.png:
        from pour_gym.report.pictures import render_points

        render_points(cloud.points, args.png, title=f"scan of {args.source}")
    doc = {"out": str(out), "n_points": len(cloud.points), "config": cfg.to_dict()}
    return (doc, lambda: f"wrote {len(cloud.points)} points to {out}")


def cmd_reconstruct(args: argparse.Namespace) -> Output:
    """Reconstruct a mesh from a scan of a catalogue object or from a point cloud file."""
    from pour_gym.mesh.fileio import load_point_cloud, save_mesh
    from pour_gym.mesh.modelgen import generate_model, reconstruct_text
    from pour_gym.mesh.reconstruct import ReconstructConfig
    from pour_gym.objects import get_spec

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
        from pour_gym.report.pictures import render_mesh

        render_mesh(result.reconstruction.mesh, args.png, title=mesh_path.stem)
        report["png"] = str(args.png)
    return (report, lambda: reconstruct_text(report))


def cmd_measure(args: argparse.Namespace) -> Output:
    """Height, rim radius and holding volume of an upright watertight mesh."""
    from pour_gym.mesh.fileio import validate_mesh
    from pour_gym.mesh.measure import container_dimensions

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
    """Reports: reconstruction (ch. 3), warping (ch. 4), generalisation, baselines, sensors."""
    from tqdm import tqdm

    from pour_gym.mesh.modelgen import generate_model, reconstruction_table
    from pour_gym.objects import OBJECT_NAMES

    if args.family and args.what not in ("warping", "generalisation"):
        raise InputError("--family is for report warping and report generalisation")
    if args.reference and args.what != "baselines":
        raise InputError("--reference is for report baselines")
    if args.what == "generalisation" and args.family:
        from pour_gym.agents.evaluation.family import family_study, write_family_study

        if not args.out:
            raise InputError("report generalisation --family needs --out DIR")
        policies = [name for name in args.policies.split(",") if name]
        perceptions = tuple(p for p in args.perception.split(",") if p)
        doc = family_study(args.family, policies, args.episodes, args.seed, perceptions,
                           args.scan_seed, args.liquids, args.workers)  # fmt: skip
        out = write_family_study(doc, args.out)
        return (doc, lambda: (out / "report.md").read_text())
    if args.what == "sensors":
        from pour_gym.apps.sensor_pictures import sensor_sheets
        from pour_gym.envs import PANDA_POUR_V0, PARTICLE_DROP_V0, POUR_V0, TILT_POUR_V0

        if not args.out:
            raise InputError("report sensors needs --out DIR (for a PNG per environment)")
        paths = sensor_sheets(
            [POUR_V0, PANDA_POUR_V0, TILT_POUR_V0, PARTICLE_DROP_V0], args.out, args.seed
        )
        doc = {"pictures": [str(p) for p in paths]}
        return (doc, lambda: "\n".join(doc["pictures"]))
    if args.what == "baselines":
        from pour_gym.agents.evaluation.baselines import REPORT, baselines_report

        doc = baselines_report(args.runs, reference=args.reference)
        return (doc, lambda: REPORT.read_text())
    if args.what == "generalisation":
        from pour_gym.agents.evaluation.generalisation import study_report

        if not args.runs or not args.out:
            raise InputError(
                "report generalisation needs --runs DIR and --out DIR (or --family FAMILY)"
            )
        summary = study_report(args.runs, args.out)
        return (summary, lambda: (Path(args.out) / "report.md").read_text())
    if args.what == "warping" and args.family:
        from pour_gym.agents.evaluation.family import family_warping, family_warping_report

        doc = family_warping(args.family)
        return (doc, lambda: family_warping_report(doc))
    if args.what == "warping":
        from pour_gym.assets import label_container
        from pour_gym.report.warping_tables import warping_tables

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
        lip = asset.meta["source"].get("transfer", {}).get("lip")
        if lip is not None:
            lines.append(
                f"  rim fitted to the lip, {lip['depth'] * 1e3:.1f} mm deep"
                if lip["depth"] is not None
                else f"  rim as warped (the lip could not be told: {lip['reason']})"
            )
        if "iou" in asset.meta:
            iou = ", ".join(f"{k} {v:.3f}" for k, v in asset.meta["iou"].items() if v is not None)
            lines.append(f"  IoU against ground truth: {iou}")
        return "\n".join(lines)

    return (doc, text)


def cmd_build_assets(args: argparse.Namespace) -> Output:
    """Label containers ahead of time: the packaged catalogue, or any containers' caches."""
    from tqdm import tqdm

    from pour_gym.assets import (
        CATALOGUE,
        asset_root,
        expand_containers,
        label_container,
        write_asset,
    )

    if args.objects:
        from pour_gym.apps.prepare import prepare_containers

        names = expand_containers(args.objects)
        rows = prepare_containers(names, args.jobs, args.perceive, args.scan_seed)
        refused = [r for r in rows if r["refused"]]

        def summary() -> str:
            seconds = sum(r["seconds"] for r in rows)
            lines = [
                f"{len(rows) - len(refused)} of {len(rows)} containers labelled and their "
                f"fields cached ({seconds:.0f} s of work); envs now load them from the caches"
            ]
            lines += [f"  refused: {r['name']}: {r['refused']}" for r in refused]
            return "\n".join(lines)

        return ({"containers": rows}, summary)
    root = Path(args.out) if args.out else asset_root()
    done = {}
    for name in tqdm(CATALOGUE, desc="build assets", file=sys.stderr):
        asset = label_container(name, args.source, args.method)
        done[name] = str(write_asset(asset, root / name))
    return (done, lambda: f"wrote {len(done)} assets under {root}")


def number_list(text: str, what: str, kind: type = int) -> list:
    """A comma-separated option's numbers, each above 0 (``--sizes 300,1000``).

    Args:
        text: the option's value.
        what: what the numbers are, with an example, for the error (``"particle counts
            (e.g. 300,1000)"``).
        kind: ``int`` or ``float``.

    Raises:
        InputError: naming the first value that is not a number of that kind above 0.
    """
    numbers = []
    for item in text.split(","):
        try:
            value = kind(item.strip())
        except ValueError:
            value = None
        if value is None or not value > 0:
            raise InputError(f"{item.strip()!r} in {text!r} is not one of {what}")
        numbers.append(value)
    return numbers


def cmd_bench(args: argparse.Namespace) -> Output:
    """Benchmarks; every result names the machine it ran on (``machine`` in the JSON)."""
    from pour_gym.apps.bench.machine import machine, machine_line

    doc, text = _bench(args)
    info = machine()
    return ({**doc, "machine": info}, lambda: f"{machine_line(info)}\n{text()}")


def _bench(args: argparse.Namespace) -> Output:
    """The benchmark ``args.what`` asks for."""
    from pour_gym.apps.bench import (
        DEFAULT_SECTIONS,
        accuracy_table,
        bench_accuracy,
        bench_coldstart,
        bench_envs,
        bench_fluid,
        bench_label,
        bench_ray,
        bench_reconstruct,
        coldstart_table,
        envs_table,
        fluid_table,
        label_table,
        ray_table,
        reconstruct_table,
    )
    from pour_gym.envs import ENV_IDS

    if args.what == "fluid":
        counts = "particle counts (e.g. 300,1000)"
        sizes = number_list(args.sizes or "300,1000,2000,4000,16000", counts)
        bullet = number_list(args.bullet_sizes, counts) if args.bullet_sizes else []
        result = bench_fluid(sizes, bullet, repeats=args.repeats)
        doc = {k: v for k, v in result.items() if k != "rows"}
        return (doc, lambda: fluid_table(result))
    if args.what == "accuracy":
        result = bench_accuracy(spacing=args.spacing)
        return (result, lambda: accuracy_table(result))
    if args.what == "liquids":
        from pour_gym.apps.bench.liquids import bench_liquid_cost, liquid_cost_table

        result = bench_liquid_cost(repeats=args.repeats)
        return (result, lambda: liquid_cost_table(result))
    if args.what == "flows":
        from pour_gym.apps.bench.liquids import bench_flows, flows_table

        result = bench_flows(out=args.out)
        return (result, lambda: flows_table(result))
    if args.what == "efflux":
        from pour_gym.apps.bench.liquids import bench_efflux, efflux_table

        spacings = "particle spacings in mm (e.g. 5,3.5,2.5)"
        mm = number_list(args.sizes, spacings, float) if args.sizes else [5, 3.5, 2.5]
        scales = number_list(args.scales, "vessel scales (e.g. 1,2)", float)
        result = bench_efflux(tuple(m / 1000 for m in mm), tuple(scales))
        return (result, lambda: efflux_table(result))
    if args.what == "viscosity":
        from pour_gym.apps.bench.liquids import bench_viscosity, viscosity_table

        result = bench_viscosity(
            args.spacing, calibrate=args.part != "liquids", liquids=args.part != "calibration"
        )
        return (result, lambda: viscosity_table(result))
    if args.what == "coldstart":
        ids = args.envs.split(",") if args.envs else list(ENV_IDS)
        result = bench_coldstart(ids)
        return (result, lambda: coldstart_table(result))
    if args.what == "envs":
        sections = tuple(args.sections.split(",")) if args.sections else DEFAULT_SECTIONS
        result = bench_envs(repeats=args.repeats, sections=sections)
        return (result, lambda: envs_table(result))
    if args.what == "ray":
        result = bench_ray(repeats=args.repeats)
        return (result, lambda: ray_table(result))
    if args.what == "label":
        sizes = number_list(args.sizes or "5000,10000,20000,40000", "vertex counts (e.g. 5000)")
        rows = bench_label(sizes, repeats=args.repeats)
        return ({"label": rows}, lambda: label_table(rows))
    sizes = number_list(args.sizes or "5000,10000,25000,50000,100000", "point counts (e.g. 5000)")
    rows = bench_reconstruct(sizes, repeats=args.repeats)
    return ({"reconstruct": rows}, lambda: reconstruct_table(rows))


def cmd_soak(args: argparse.Namespace) -> Output:
    """Random actions over containers: exceptions, false endings, lost particles, walls."""
    from pour_gym.apps.soak import soak, soak_table
    from pour_gym.assets import expand_containers

    objects = list(expand_containers(args.objects)) if args.objects else None
    if args.user_meshes or objects is None:
        from pour_gym.apps.soak import user_meshes
        from pour_gym.io.cache import cache_dir

        if objects is not None:
            objects += user_meshes(cache_dir("soak"))
    if args.episodes < 1 or args.steps < 1:
        raise InputError("--episodes and --steps must be at least 1")
    if args.liquids:
        from pour_gym.apps.soak import soak_liquids

        liquids = [x.strip() for x in args.liquids.split(",") if x.strip()]
        doc = soak_liquids(liquids, args.env, objects, args.episodes, args.steps, args.seed)
    else:
        doc = soak(args.env, objects, args.episodes, args.steps, args.seed)
    return (doc, lambda: soak_table(doc))
