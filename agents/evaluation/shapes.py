"""A family evaluation's rows grouped by the members' shape parameters.

Used by every evaluation over a family (``eval.md``, ``pour-gym evaluate``:
:func:`shape_section`) and by the generalisation study
(:func:`pour_gym.agents.evaluation.family.family_study`); the grouping itself is
:mod:`pour_gym.report.family`'s.
"""

from __future__ import annotations

from pour_gym.agents.evaluation.aggregate import wilson_interval
from pour_gym.objects.procedural import is_member, member_spec
from pour_gym.report.family import bucket_tables, by_bucket

VALUES = ("success", "amount_error", "spilled")
# A family evaluation's table by shape: the scores, then the failures by why.
SHAPE_VALUES = (*VALUES, "outcome_overshot", "outcome_under_poured", "outcome_spilled")


def member_buckets(
    rows: list[dict], episodes: int, values: tuple[str, ...] = VALUES
) -> tuple[list[dict], dict[str, dict[str, dict]]]:
    """Evaluation rows of members poured into themselves, grouped by each shape parameter.

    Args:
        rows: :func:`~pour_gym.agents.evaluation.evaluate.evaluate_policy` rows whose
            source is a procedural member.
        episodes: episodes per row.
        values: the row values to average in each bucket (``success`` among them).

    Returns:
        The rows with their member's parameters (``"spec"``), and
        :func:`~pour_gym.report.family.by_bucket` of them, each bucket's success with a 95 %
        Wilson interval over its episodes (``"success_interval"``).
    """
    rows = [{**r, "spec": member_spec(r["source"]).to_dict()} for r in rows]
    buckets = by_bucket(rows, values)
    for groups in buckets.values():
        for bucket in groups.values():
            k = bucket["members"] * episodes
            bucket["success_interval"] = wilson_interval(bucket["success"] * k, k)
    return rows, buckets


def shape_section(result: dict) -> str | None:
    """Markdown of an evaluation over a family, by shape parameter; None for other ones.

    Where every row pours a procedural member into itself (``pour-gym evaluate ...
    --objects procedural:test``, a training's evaluation over a family), the rows are
    grouped by each parameter of the members (profile, cross-section, lip, handle, binned
    height, rim radius and wall): which shapes a policy pours and which it fails, and why
    (the share of episodes overshot, under-poured and spilled).
    """
    rows = result["rows"]
    if not rows or not all(
        is_member(r["object"]) and r.get("source", r["object"]) == r.get("target", r["object"])
        for r in rows
    ):
        return None
    _, buckets = member_buckets(rows, result["episodes"], SHAPE_VALUES)
    return (
        "## By shape\n\nThe members grouped by each of their parameters: mean success, "
        "amount error (particles) and spill per episode, and the share of episodes that "
        "overshot, under-poured or spilled.\n\n" + bucket_tables(buckets, SHAPE_VALUES)
    )
