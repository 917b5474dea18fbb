"""The fluid's accuracy: settled columns, pour onsets and a shear wave.

See :mod:`pour_gym.fluid.validation`.
"""

from __future__ import annotations

import sys
from dataclasses import asdict

from tqdm import tqdm

from pour_gym.report.tables import markdown_table

COLUMNS = (0.025, 0.05, 0.072, 0.086)  # m: a shallow cup to a full thesis cup
FILLS = (0.6, 0.7, 0.8)


def bench_accuracy(
    heights: tuple[float, ...] = COLUMNS, fills: tuple[float, ...] = FILLS, spacing: float = 0.005
) -> dict:
    """Settle columns, tilt filled cups, and watch a shear wave in a tray.

    Args:
        heights: the columns' heights, m.
        fills: the cups' fills, fractions of their depth.
        spacing: the particles' spacing, m (the envs' ``spacing=``).

    Returns:
        ``{"columns": [Column as dict, ...], "onsets": [Onset as dict, ...], "shear":
        ShearWave as dict}`` (see :class:`pour_gym.fluid.validation.Column`, ``Onset`` and
        ``ShearWave``; the wave's time series as lists).
    """
    from pour_gym.fluid.pbf import PBFConfig
    from pour_gym.fluid.validation import (
        COLUMN_HEIGHT,
        ONSET_HEIGHT,
        cylinder_field,
        pour_onset,
        settled_column,
        shear_wave,
    )

    bar = tqdm(total=len(heights) + len(fills) + 1, desc="bench accuracy", file=sys.stderr)
    tall, cup = cylinder_field(COLUMN_HEIGHT), cylinder_field(ONSET_HEIGHT)
    config = PBFConfig(spacing=spacing)
    columns, onsets = [], []
    for height in heights:
        columns.append(asdict(settled_column(height, config, field=tall)))
        bar.update()
    for fill in fills:
        onsets.append(asdict(pour_onset(fill, config, field=cup)))
        bar.update()
    wave = asdict(shear_wave(config=config))
    wave = {k: v.tolist() if hasattr(v, "tolist") else v for k, v in wave.items()}
    bar.update()
    bar.close()
    return {"spacing": spacing, "columns": columns, "onsets": onsets, "shear": wave}


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
    tables = columns + "\n\n" + onsets
    wave = result.get("shear")
    if wave:
        tables += "\n\n" + markdown_table(
            ["shear wave: length, cm", "speed, m/s", "elastic wave speed, m/s (a liquid: 0)",
             "viscosity, m^2/s (water 1e-6)"],
            [[f"{wave['wavelength'] * 100:.0f}", f"{wave['amplitude']:.3f}",
              f"{wave['wave_speed']:.3f}", f"{wave['viscosity']:.2e}"]],
        )  # fmt: skip
    return tables
