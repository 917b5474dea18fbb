"""The model-generation pipeline of chapter 3, end to end, with a report.

``scan -> reconstruct -> measure``: a catalogue object is scanned on the simulated
turntable, or a user's cloud is read; both inner-surface models are reconstructed; the
chosen one is the result, and the report holds the measured height, rim radius and volume
of both, compared with ground truth (and with the thesis's own errors) when the object is
from the catalogue.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from pour_gym.mesh.measure import chamfer_distance, container_dimensions
from pour_gym.mesh.reconstruct import ReconstructConfig, Reconstruction, reconstruct
from pour_gym.mesh.scan import PointCloud, ScanConfig, turntable_scan
from pour_gym.objects import build_object
from pour_gym.report.tables import markdown_table, text_table

MODELS = ("thesis", "offset")


@dataclass
class ModelGeneration:
    """Result of the pipeline.

    Attributes:
        cloud: the input cloud (scanned or read).
        reconstructions: one reconstruction per inner model, by model name.
        chosen: the model whose mesh is the result.
        report: JSON-serialisable report (see :func:`generate_model`).
    """

    cloud: PointCloud
    reconstructions: dict[str, Reconstruction]
    chosen: str
    report: dict

    @property
    def reconstruction(self) -> Reconstruction:
        """The chosen model's reconstruction."""
        return self.reconstructions[self.chosen]


def _errors(measured: float, truth: float) -> dict[str, float]:
    return {
        "measured": measured,
        "truth": truth,
        "abs_error": abs(measured - truth),
        "rel_error": abs(measured - truth) / truth,
    }


def generate_model(
    obj: str | None = None,
    cloud: PointCloud | None = None,
    config: ReconstructConfig | None = None,
    scan_config: ScanConfig | None = None,
) -> ModelGeneration:
    """Run scan (or read cloud) -> reconstruct (both inner models) -> measure.

    Args:
        obj: a catalogue object to scan and compare with; exclusive with ``cloud``.
        cloud: a user's cloud, in m, upright.
        config: reconstruction settings; ``config.inner`` picks the resulting model.
        scan_config: scanner settings for ``obj``.

    Returns:
        The reconstructions and the report: ``n_points``, ``seconds`` (total wall time),
        per model ``height``, ``rim_radius``, ``volume`` (m, m^3), and for a catalogue
        object per model ``errors`` against the thesis's real values and the
        ``chamfer_distance`` to the ground-truth mesh (m), plus the thesis's own errors.
    """
    if (obj is None) == (cloud is None):
        raise ValueError("pass exactly one of obj and cloud")
    cfg = config or ReconstructConfig()
    t0 = time.perf_counter()
    truth = None
    if obj is not None:
        truth = build_object(obj)
        cloud = turntable_scan(truth.mesh, truth.labels, scan_config)
    assert cloud is not None
    recs: dict[str, Reconstruction] = {}
    models: dict[str, dict] = {}
    for model in MODELS:
        rec = reconstruct(cloud, dataclasses.replace(cfg, inner=model))
        recs[model] = rec
        dims = container_dimensions(rec.mesh)
        entry: dict = {
            "height": dims.height,
            "rim_radius": dims.rim_radius,
            "volume": dims.volume,
            "watertight": bool(rec.mesh.is_watertight),
            "vertices": len(rec.mesh.vertices),
            "faces": len(rec.mesh.faces),
            "n_inducing": rec.n_inducing,
            "field_level": rec.level,
            "stage_seconds": rec.seconds,
        }
        if truth is not None:
            spec = truth.spec
            entry["errors"] = {
                "height": _errors(dims.height, spec.height),
                "rim_radius": _errors(dims.rim_radius, spec.rim_radius),
                "volume": _errors(dims.volume, spec.volume),
            }
            entry["chamfer_distance"] = chamfer_distance(rec.mesh, truth.mesh)
        models[model] = entry
    report: dict = {
        "object": obj,
        "source": cloud.meta.get("source"),
        "n_points": len(cloud.points),
        "inner": cfg.inner,
        "config": cfg.to_dict(),
        "models": models,
        "seconds": time.perf_counter() - t0,
    }
    if truth is not None:
        spec = truth.spec
        report["ground_truth"] = {
            "height": spec.height,
            "rim_radius": spec.rim_radius,
            "volume": spec.volume,
        }
        report["thesis"] = {
            "height": _errors(spec.thesis_height, spec.height),
            "rim_radius": _errors(spec.thesis_rim_radius, spec.rim_radius),
            "volume": _errors(spec.thesis_volume, spec.volume),
        }
        report["scan"] = (scan_config or ScanConfig()).to_dict()
    report = _plain(report)
    return ModelGeneration(cloud=cloud, reconstructions=recs, chosen=cfg.inner, report=report)


def _plain(value):
    """Turn numpy scalars in nested dicts and lists into Python numbers for JSON."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def reconstruct_text(report: dict) -> str:
    """A table of the report's dimensions per model (and errors for catalogue objects)."""
    rows = []
    for model, m in report["models"].items():
        err = m.get("errors")
        row = [
            model + (" *" if model == report["inner"] else ""),
            f"{m['height'] * 100:.2f}",
            f"{m['rim_radius'] * 100:.2f}",
            f"{m['volume'] * 1e6:.1f}",
        ]
        if err:
            row += [
                f"{err['height']['rel_error']:.1%}",
                f"{err['rim_radius']['rel_error']:.1%}",
                f"{err['volume']['rel_error']:.1%}",
                f"{m['chamfer_distance'] * 1000:.2f}",
            ]
        rows.append(row)
    header = ["model", "height cm", "radius cm", "volume ml"]
    if "thesis" in report:
        t = report["thesis"]
        rows.append(
            [
                "thesis (paper)",
                f"{t['height']['measured'] * 100:.2f}",
                f"{t['rim_radius']['measured'] * 100:.2f}",
                f"{t['volume']['measured'] * 1e6:.1f}",
                f"{t['height']['rel_error']:.1%}",
                f"{t['rim_radius']['rel_error']:.1%}",
                f"{t['volume']['rel_error']:.1%}",
                "-",
            ]
        )
        header += ["height err", "radius err", "volume err", "chamfer mm"]
    lines = [
        f"{report['n_points']} points, {report['seconds']:.1f} s; mesh: {report['mesh']} "
        f"(report {report['report']}); * = the written model",
        text_table(rows, header),
    ]
    return "\n".join(lines)


def reconstruction_table(reports: dict[str, dict]) -> str:
    """Markdown table of relative errors per object: thesis paper, thesis model, offset."""
    quantities = ("height", "rim_radius", "volume")
    header = [
        "object",
        *(f"{q} {src}" for q in ("height", "radius", "volume")
          for src in ("paper", "thesis", "offset")),
        "chamfer mm (thesis / offset)",
    ]  # fmt: skip
    rows = []
    sums = np.zeros(9)
    for name, r in reports.items():
        cells = []
        for q in quantities:
            cells += [
                r["thesis"][q]["rel_error"],
                r["models"]["thesis"]["errors"][q]["rel_error"],
                r["models"]["offset"]["errors"][q]["rel_error"],
            ]
        sums += cells
        chamfer = "{:.2f} / {:.2f}".format(
            r["models"]["thesis"]["chamfer_distance"] * 1000,
            r["models"]["offset"]["chamfer_distance"] * 1000,
        )
        rows.append([name, *(f"{c:.1%}" for c in cells), chamfer])
    mean = sums / len(reports)
    rows.append(["**mean**", *(f"**{c:.1%}**" for c in mean), ""])
    return markdown_table(header, rows)
