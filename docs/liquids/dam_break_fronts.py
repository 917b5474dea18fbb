"""The dam break's front against two experiments, and whether the column was at rest.

For each particle spacing (mm, default 5): the column's rms particle speed when the dam
goes (``DamBreak.settled_speed``), how squeezed its base is then (the 90th percentile of
the particles' density over rest, ``DamBreak.settled_compression``), and the front over
Martin and Moyce's (1952, a = 2.25 in) and over Koshizuka and Oka's (1996) at each of
their times up to T = t sqrt(2 g / a) = 3.4, with Ritter's inviscid front over theirs in
brackets (x / a = 1 + 2 T for a column 2a high). ``--iterations`` changes the solver's
constraint iterations (the envs' 4), ``--width`` scales the column's width a (and its
height 2a), ``--settle-damping`` takes that share of the particles' velocity away after
each step of the hold, ``--substep-rate`` sets the fluid's substeps per second (at least;
the envs' 240). About 10 s a run at 5 mm, 30 s at 2.5 mm, one thread
(docs/liquids.md, "Flows with known answers").

    python docs/liquids/dam_break_fronts.py 5 4 3.5 3 2.5
    python docs/liquids/dam_break_fronts.py 5 --iterations 16
    python docs/liquids/dam_break_fronts.py 5 --width 1.43
    python docs/liquids/dam_break_fronts.py 5 3.5 --settle-damping 0.5
    python docs/liquids/dam_break_fronts.py 5 4 3.5 --substep-rate 480
"""

import argparse
import dataclasses

import numpy as np

from pour_gym.envs.base import fluid_config_at
from pour_gym.fluid.flows import DAM_WIDTH, KOSHIZUKA_OKA, MARTIN_MOYCE, dam_break

EXPERIMENTS = {
    "Martin and Moyce": MARTIN_MOYCE["a = 2.25 in"],
    "Koshizuka and Oka": KOSHIZUKA_OKA,
}
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("spacings", nargs="*", type=float, default=[5.0], help="mm")
parser.add_argument("--iterations", type=int, help="the solver's (default: the envs')")
parser.add_argument("--width", type=float, default=1.0, help="a over Martin and Moyce's")
parser.add_argument("--settle-damping", type=float, default=0.0, help="share, each hold step")
parser.add_argument("--substep-rate", type=float, help="substeps per second (the envs': 240)")
args = parser.parse_args()
for mm in args.spacings:
    config = fluid_config_at(None, mm / 1000)
    if args.iterations:
        config = dataclasses.replace(config, iterations=args.iterations)
    if args.substep_rate:
        config = dataclasses.replace(config, substep=1.0 / args.substep_rate)
    run = dam_break(width=args.width * DAM_WIDTH, config=config, num_threads=1,
                    settle_damping=args.settle_damping)  # fmt: skip
    print(f"{mm:g} mm, {config.iterations} iterations, substeps of 1/{1 / config.substep:g} s, "
          f"a = {1000 * run.width:.1f} mm, "
          f"settle damping {args.settle_damping:g}: at release the column's rms speed "
          f"{run.settled_speed:.3f} m/s, its density over rest (90th percentile) "
          f"{run.settled_compression:.3f}")  # fmt: skip
    for name, (times, fronts) in EXPERIMENTS.items():
        pairs = [(t, z) for t, z in zip(times, fronts, strict=True) if 0 < t <= 3.4]
        ours = np.interp([t for t, _ in pairs], run.times, run.fronts)
        cells = "  ".join(f"T {t:.2f}: {x / z:.2f} ({(1 + 2 * t) / z:.1f})"
                          for (t, z), x in zip(pairs, ours, strict=True))  # fmt: skip
        print(f"  front / {name}'s: {cells}")
