"""The deep columns and the full cup's onset at a fine spacing, by constraint iterations.

    python docs/liquids/fine_iterations.py ITERATIONS[,ITERATIONS...] SPACING_M

Prints, per iteration count, the 7.2 and 8.6 cm columns' height error (%), bulk density
error (%) and rms speed (m/s) after 2.5 s, and the onset error (deg) of the cylinder
filled to 0.8 of its depth (pour_gym.fluid.validation; docs/liquids.md).
"""

import sys

from pour_gym.fluid.pbf import PBFConfig
from pour_gym.fluid.validation import (
    COLUMN_HEIGHT,
    ONSET_HEIGHT,
    cylinder_field,
    pour_onset,
    settled_column,
)

tall, cup = cylinder_field(COLUMN_HEIGHT), cylinder_field(ONSET_HEIGHT)
for iterations in (int(x) for x in sys.argv[1].split(",")):
    config = PBFConfig(spacing=float(sys.argv[2]), iterations=iterations)
    for height in (0.072, 0.086):
        c = settled_column(height, config, num_threads=1, field=tall)
        print(
            f"{iterations} iterations, {height * 100:.1f} cm column: height "
            f"{c.height_error:+.2%}, density {c.density_error:.2%}, {c.rms_speed:.3f} m/s"
        )
    onset = pour_onset(0.8, config, num_threads=1, field=cup)
    print(f"{iterations} iterations, fill 0.8: onset {onset.error_deg:+.2f} deg")
