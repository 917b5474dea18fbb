"""Results over a procedural family, by shape parameter: where a method holds and where not.

Each member of a family (:mod:`pour_gym.objects.procedural`) is one row: its parameters and
what was measured on it (the warping's IoU per part, a policy's success). :func:`by_bucket`
groups the rows by each parameter, the categorical ones by value and the lengths by
fixed bins, and averages every measured value in each group; :func:`bucket_tables` writes
that as markdown. The studies themselves (warping, policies) are in
:mod:`pour_gym.agents.evaluation.family`.
"""

from __future__ import annotations

import numpy as np

from pour_gym.report.tables import markdown_table

CATEGORIES = ("profile", "cross_section", "lip", "handle")
# Bin edges of the lengths, m (the family's ranges, in 4-5 bins each).
BINS: dict[str, tuple[float, ...]] = {
    "height": (0.04, 0.06, 0.08, 0.10, 0.12, 0.14),
    "rim_radius": (0.025, 0.04, 0.055, 0.07, 0.085),
    "wall": (0.002, 0.003, 0.004, 0.005, 0.006),
}
PARTS = ("rim", "handle", "container")


def bucket_of(spec: dict, parameter: str) -> str:
    """The bucket of a member's parameter: its value, or its bin ``"4-6 cm"``/``"2-3 mm"``."""
    value = spec[parameter]
    if parameter in CATEGORIES:
        return ("with handle" if value else "no handle") if parameter == "handle" else str(value)
    edges = BINS[parameter]
    k = int(np.clip(np.searchsorted(edges, value, side="right") - 1, 0, len(edges) - 2))
    unit, factor = ("mm", 1e3) if parameter == "wall" else ("cm", 1e2)
    return f"{edges[k] * factor:g}-{edges[k + 1] * factor:g} {unit}"


def by_bucket(rows: list[dict], values: tuple[str, ...]) -> dict[str, dict[str, dict]]:
    """Group rows by each parameter's bucket and average the values in each.

    Args:
        rows: one per member: ``{"spec": its parameters, value: number or None, ...}``
            (None: not measured on it, e.g. the handle's IoU of a member without one).
        values: the keys to average.

    Returns:
        ``{parameter: {bucket: {"members": n, value: mean or None, ...}}}``, buckets in
        their natural order.
    """
    out: dict[str, dict[str, dict]] = {}
    for parameter in (*CATEGORIES, *BINS):
        groups: dict[str, list[dict]] = {}
        for row in rows:
            groups.setdefault(bucket_of(row["spec"], parameter), []).append(row)
        order = sorted(groups, key=lambda b: _bucket_key(parameter, b))
        out[parameter] = {b: mean_of(groups[b], values) for b in order}
    return out


def _bucket_key(parameter: str, bucket: str):
    if parameter in BINS:
        return float(bucket.split("-")[0])
    return bucket


def mean_of(rows: list[dict], values: tuple[str, ...]) -> dict:
    """``{"members": len(rows), value: the mean over the rows that have it, or None}``."""
    summary: dict = {"members": len(rows)}
    for key in values:
        measured = [r[key] for r in rows if r.get(key) is not None]
        summary[key] = float(np.mean(measured)) if measured else None
    return summary


def _cell(bucket: dict, value: str) -> str:
    """A bucket's mean of a value; the success with its interval where it has one."""
    if bucket[value] is None:
        return "-"
    interval = bucket.get(f"{value}_interval")
    return f"{bucket[value]:.3f}" + (f" [{interval[0]:.2f}, {interval[1]:.2f}]" if interval else "")


def bucket_tables(summary: dict[str, dict[str, dict]], values: tuple[str, ...]) -> str:
    """Markdown: one table per parameter, a row per bucket, a column per value.

    A value with an interval in the bucket (``"success_interval"``) is followed by it in
    brackets; an outcome's share of the episodes (``outcome_under_poured``) is headed
    ``under-poured (share)``.
    """
    names = [
        f"{v.removeprefix('outcome_').replace('_', '-')} (share)"
        if v.startswith("outcome_")
        else v.replace("_", " ")
        for v in values
    ]
    blocks = []
    for parameter, buckets in summary.items():
        rows = [
            [bucket, str(s["members"]), *(_cell(s, v) for v in values)]
            for bucket, s in buckets.items()
        ]
        header = [parameter.replace("_", " "), "members", *names]
        blocks.append(f"### by {parameter.replace('_', ' ')}\n\n" + markdown_table(header, rows))
    return "\n\n".join(blocks)
