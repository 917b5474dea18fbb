"""The fluid's accuracy: settled columns and pour onsets (:mod:`pour_gym.fluid.validation`)."""

from __future__ import annotations

import sys
from dataclasses import asdict

from tqdm import tqdm

from pour_gym.report.tables import markdown_table

COLUMNS = (0.025, 0.05, 0.072, 0.086)  # m: a shallow cup to a full thesis cup
FILLS = (0.6, 0.7, 0.8)


def bench_accuracy(heights: tuple[float, ...] = COLUMNS, fills: tuple[float, ...] = FILLS) -> dict:
    """Settle columns of the given heights and tilt cups filled to the given fractions.

    Returns:
        ``{"columns": [Column as dict, ...], "onsets": [Onset as dict, ...]}`` (see
        :class:`pour_gym.fluid.validation.Column` and ``Onset``).
    """
    from pour_gym.fluid.validation import (
        COLUMN_HEIGHT,
        ONSET_HEIGHT,
        cylinder_field,
        pour_onset,
        settled_column,
    )

    bar = tqdm(total=len(heights) + len(fills), desc="bench accuracy", file=sys.stderr)
    tall, cup = cylinder_field(COLUMN_HEIGHT), cylinder_field(ONSET_HEIGHT)
    columns, onsets = [], []
    for height in heights:
        columns.append(asdict(settled_column(height, field=tall)))
        bar.update()
    for fill in fills:
        onsets.append(asdict(pour_onset(fill, field=cup)))
        bar.update()
    bar.close()
    return {"columns": columns, "onsets": onsets}


def _percent(x: float) -> str:
    return "no bulk" if x != x else f"{x:.2%}"  # NaN: a column too shallow for a bulk


def accuracy_table(result: dict) -> str:
    """Markdown tables of :func:`bench_accuracy`, with the limits the tests assert."""
    columns = markdown_table(
        ["column N v / (pi R^2), cm", "measured, cm", "error (limit 5 %)",
         "bulk density error (limit 3 %)", "rms speed, m/s", "lost"],
        [[f"{c['height'] * 100:.1f}", f"{c['measured'] * 100:.2f}",
          f"{c['height_error']:+.2%}", _percent(c["density_error"]), f"{c['rms_speed']:.3f}",
          c["lost"]] for c in result["columns"]],
    )  # fmt: skip
    onsets = markdown_table(
        ["fill", "expected onset, deg", "measured, deg", "error (limit 3 deg)"],
        [[f"{o['fill']:.1f}", f"{o['expected_deg']:.1f}", f"{o['measured_deg']:.1f}",
          f"{o['error_deg']:+.2f}"] for o in result["onsets"]],
    )  # fmt: skip
    return columns + "\n\n" + onsets
