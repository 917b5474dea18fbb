"""The helper process of :mod:`pour_gym.fluid.precompile`: compiles builds into numba's cache.

Run as ``python -c "from pour_gym.fluid.compile_helper import main; main([...])"`` by
:func:`pour_gym.fluid.precompile.start` (never imported by the library: it imports the
kernel, which imports :mod:`~pour_gym.fluid.precompile`). Each build is compiled under its
lock in the cache directory and marked when done; the name of each build is printed on
stdout as it is ready, and a line on stderr says whether it was compiled or found.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from pour_gym.fluid.build import BUILDS
from pour_gym.fluid.pbf import PBFluid
from pour_gym.fluid.precompile import cache_dir, lock, locked, marker
from pour_gym.fluid.sdf import SignedDistanceField


def _tiny_fluid(threads: int):
    """A few particles over a slab (no mesh, no open3d): enough to compile with."""
    g = np.arange(3) * 0.005
    particles = np.stack(np.meshgrid(g, g, g + 0.02, indexing="ij"), -1).reshape(-1, 3)
    nodes = np.arange(-0.02, 0.04, 0.005)
    slab = np.broadcast_to(nodes[None, None, :] - 0.004, (12, 12, 12)).copy()
    fluid = PBFluid(particles, floor=0.0, num_threads=threads)
    fluid.add_collider(SignedDistanceField(slab, np.full(3, -0.02), 0.005))
    return fluid


def compile_build(build: str) -> None:
    """Compile one build into numba's cache (a step of a tiny fluid).

    Args:
        build: ``"serial"`` or ``"parallel"``. Only the driver is cached: its parts are
            compiled with it (:data:`pour_gym.fluid.sdf.PART_CACHE`), as in any process.
    """
    _tiny_fluid(2 if build == "parallel" else 1).step(1 / 60)


def main(builds: list[str]) -> int:
    """Compile the builds named, in order, each under its lock; print each when done."""
    unknown = [b for b in builds if b not in BUILDS]
    if unknown:
        sys.stderr.write(f"unknown builds {unknown}; choose from {BUILDS}\n")
        return 2
    directory = cache_dir()
    if directory is None:
        return 1
    directory.mkdir(parents=True, exist_ok=True)
    for build in builds:
        with locked(lock(build)):
            if marker(build).is_file():
                sys.stderr.write(f"pour-gym precompile: {build} found in the cache\n")
            else:
                start = time.perf_counter()
                compile_build(build)
                marker(build).touch()
                seconds = time.perf_counter() - start
                sys.stderr.write(f"pour-gym precompile: {build} compiled in {seconds:.1f} s\n")
        print(build, flush=True)
    return 0
