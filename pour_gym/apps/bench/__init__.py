"""Benchmarks: ``pour-gym bench ...``. Timings are medians of repeated runs in one session.

Where a benchmark compares two cases, it alternates them run by run and reports the
median of the ratios within each pair: this machine's speed drifts by 2x over minutes.

- :mod:`~pour_gym.apps.bench.mesh`: reconstruction and labelling.
- :mod:`~pour_gym.apps.bench.fluid`: the fluids.
- :mod:`~pour_gym.apps.bench.accuracy`: the fluid's accuracy (not a timing).
- :mod:`~pour_gym.apps.bench.envs`: the environments.
- :mod:`~pour_gym.apps.bench.coldstart`: a new process's start.
- :mod:`~pour_gym.apps.bench.ray`: Ray.
"""

from pour_gym.apps.bench.accuracy import accuracy_table, bench_accuracy
from pour_gym.apps.bench.coldstart import bench_coldstart, coldstart_table
from pour_gym.apps.bench.envs import DEFAULT_SECTIONS, ENV_SECTIONS, bench_envs, envs_table
from pour_gym.apps.bench.fluid import bench_fluid, fluid_table
from pour_gym.apps.bench.mesh import bench_label, bench_reconstruct, label_table, reconstruct_table
from pour_gym.apps.bench.ray import bench_ray, ray_table

__all__ = [
    "DEFAULT_SECTIONS",
    "ENV_SECTIONS",
    "accuracy_table",
    "bench_accuracy",
    "bench_coldstart",
    "bench_envs",
    "bench_fluid",
    "bench_label",
    "bench_ray",
    "bench_reconstruct",
    "coldstart_table",
    "envs_table",
    "fluid_table",
    "label_table",
    "ray_table",
    "reconstruct_table",
]
