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
from pathlib import Path

import numpy as np

from pour_gym.fluid import pbf
from pour_gym.fluid.pbf import PBFluid
from pour_gym.fluid.precompile import BUILDS, cache_dir, lock, locked, marker
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


def _call_parts(part: str) -> None:
    """Compile one part of the one-thread build by calling its functions on a tiny fluid.

    The kernel's functions are separate compilations that numba caches one by one, so two
    processes can compile two parts at once; the driver, compiled last, loads them. The
    calls pass the types the driver passes (``tests/test_precompile.py`` checks that
    compiling the driver after both parts compiles none of them again).

    Args:
        part: ``"walls"`` (collisions with the containers' fields) or ``"constraint"`` (the
            cell sort, neighbour search, density constraint, velocities and poses).
    """
    fluid = _tiny_fluid(1)
    a = fluid.kernel_arguments(1 / 60)
    serial = pbf._ADVANCE[False].py_func.__globals__  # the serial build's passes
    x, k = a["x"], len(fluid.colliders)
    p, prev, vn = a["p"], a["prev"], a["vn"]
    p[:], prev[:], vn[:] = x, x, 0.0
    eye = np.repeat(np.eye(3)[None], k, axis=0)
    zero = np.zeros((k, 3))
    near = np.zeros((len(x), k))
    radius, h, hs = a["radius"], a["h"], 1 / 240
    fields = (a["fvals"], a["fint"], a["fgeo"])
    if part == "walls":
        pbf._collide_one(p, prev, 0, 0, radius, *fields, eye, zero, eye, zero, 0.0)
        pbf._wall_term(0, p, a["wall"], 0.0, True, h, a["wall_table"], *fields, eye, zero, near)
        serial["_pass_collide"](
            p, a["p2"], prev, x, a["v"], vn, hs, a["limit"], radius, 0.0, True, a["corrected"],
            near, *fields, eye, zero, eye, zero, 0.0,
        )  # fmt: skip
        return
    n = len(x)
    lists = (a["nbr"], a["nbr_count"])
    pbf._sort_cells(p, h, len(a["start"]) - 1, a["keys"], a["order"], a["start"], a["sorted_p"],
                    a["grid"])  # fmt: skip
    serial["_pass_neighbours"](p, h * h, a["grid"], a["order"], a["start"], a["sorted_p"], *lists,
                               a["later"], a["n_later"])  # fmt: skip
    pairs = (a["pair_g"], a["pair_s"], a["lam"], True, a["wall"])
    pbf._lambda_run(0, n, p, *lists, *pairs, h, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0)
    pbf._correct_run(0, n, p, a["p2"], *lists, *pairs, 1.0)
    pbf._finish_run(0, n, x, a["v"], vn, p, *lists, h, 0.0, 0.0, True, radius, 1.0)
    pbf._pose_at(a["q0"][0], a["q1"][0], a["r0"][0], a["r1"][0], a["t0"][0], a["t1"][0], 0.5,
                 eye[0], zero[0])  # fmt: skip


def compile_build(build: str, walls_lock: Path | None = None) -> None:
    """Compile one build into numba's cache (a step of a tiny fluid).

    Args:
        build: ``"walls"`` (a part of the one-thread build, see :func:`_call_parts`),
            ``"serial"`` or ``"parallel"``.
        walls_lock: for ``"serial"``, the lock of a helper compiling the walls part: its
            other part is compiled first, then the driver once that lock is free.
    """
    if build == "walls":
        _call_parts("walls")
        return
    if build == "serial":
        _call_parts("constraint")
        if walls_lock is not None:
            with locked(walls_lock):
                pass
    _tiny_fluid(2 if build == "parallel" else 1).step(1 / 60)


def main(builds: list[str]) -> int:
    """Compile the builds named, in order, each under its lock; print each when done."""
    unknown = [b for b in builds if b not in (*BUILDS, "walls")]
    if unknown:
        sys.stderr.write(f"unknown builds {unknown}; choose from {BUILDS} and walls\n")
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
                compile_build(build, walls_lock=lock("walls"))
                marker(build).touch()
                seconds = time.perf_counter() - start
                sys.stderr.write(f"pour-gym precompile: {build} compiled in {seconds:.1f} s\n")
        print(build, flush=True)
    return 0
