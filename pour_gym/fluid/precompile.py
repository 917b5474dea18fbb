"""The fluid kernel compiled in a helper process, once per machine, while the world is built.

Numba compiles the kernel on its first call and keeps it in its on-disk cache (``cache=True``),
from which every later process loads it in a fraction of a second. The compile itself takes
10-20 s for the one-thread build and as long again for the threaded one, and a new process
would spend them inside its first ``step``. Instead, a :class:`~pour_gym.fluid.PBFluid` asks
for its build when it is created (:func:`start`): if that build is not known to be cached, a
helper process (:func:`main`) compiles it into the cache while
this process goes on building the world and resetting it, and the first step waits only for
what is left (:func:`ready`). The builds compute the same numbers bit for bit, so a process
that wants threads runs the one-thread build until the helper has the threaded one ready:
it never waits for the threaded compile at all.

Helpers take a lock in the cache directory: the workers of a vector env, the processes of a
test run or a Ray cluster started together compile each build once, the others wait and load
it. A file in the same directory marks each build as compiled (keyed by the kernel's source,
numba, Python and the CPU, as numba's own cache is), so a warm machine starts no helper.

Set ``POUR_GYM_PRECOMPILE=0`` to compile in the process that steps the fluid instead (as
numba does by itself). A helper that fails changes nothing but speed: the build is then
compiled where it is needed, after one warning.

This module keeps what it knows of the helpers in module state: compiled builds are a
property of the process (numba's dispatchers are module state too), not of one fluid.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import platform
import subprocess
import sys
import threading
import warnings
from pathlib import Path

import numba as nb

BUILDS = ("serial", "parallel")
ENV_SWITCH = "POUR_GYM_PRECOMPILE"
# A first step waits this long at most for a helper (a compile takes well under a minute).
WAIT_SECONDS = 600.0


class _Helper:
    """A running helper process and the builds it has reported compiled."""

    def __init__(self, builds: tuple[str, ...]):
        package_root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        # The helper must import this very package, installed or not.
        env["PYTHONPATH"] = os.pathsep.join(filter(None, (package_root, env.get("PYTHONPATH"))))
        env[ENV_SWITCH] = "0"  # the helper's own fluid compiles where it is (no helper's helper)
        self.builds = builds
        self.done: set[str] = set()
        self.finished = threading.Event()
        self.reported = {b: threading.Event() for b in builds}
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-c",
                "import sys; from pour_gym.fluid.precompile import main; "
                "sys.exit(main(sys.argv[1:]))",
                *builds,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            stdin=subprocess.DEVNULL,
            env=env,
            text=True,
        )
        threading.Thread(target=self._read, daemon=True, name="pour-gym precompile").start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            build = line.strip()
            if build in self.reported:
                self.done.add(build)
                self.reported[build].set()
        self.process.wait()
        self.finished.set()
        for event in self.reported.values():
            event.set()  # nothing more will come: whoever waits decides by `done`


_helpers: list[_Helper] = []
_known: set[str] = set()  # builds compiled or loaded in this process, or marked in the cache
_warned: list[bool] = []


def _forget_in_child() -> None:
    """A forked child has none of its parent's helper threads: it starts its own helpers."""
    _helpers.clear()


os.register_at_fork(after_in_child=_forget_in_child)


def enabled() -> bool:
    """Whether helpers compile the kernel (``POUR_GYM_PRECOMPILE`` is not ``0``)."""
    return (
        os.environ.get(ENV_SWITCH, "1").strip() != "0"
        and not nb.config.DISABLE_JIT
        and _cache_dir() is not None
    )


def _dispatcher(build: str):
    from pour_gym.fluid.pbf import _ADVANCE

    return _ADVANCE[build == "parallel"]


def _cache_dir() -> Path | None:
    """The directory numba caches the kernel in (``None`` if it cannot tell)."""
    try:
        return Path(_dispatcher("serial")._cache._cache_path)
    except AttributeError:  # a numba without this attribute: no helpers
        return None


def _key() -> str:
    """What a cached build depends on: the kernel's source, numba, Python and the CPU."""
    import llvmlite.binding as llvm

    here = Path(__file__).parent
    digest = hashlib.sha256()
    for name in ("pbf.py", "sdf.py"):
        digest.update((here / name).read_bytes())
    for part in (
        nb.__version__,
        sys.version,
        platform.machine(),
        llvm.get_host_cpu_name(),
        llvm.get_host_cpu_features().flatten(),
    ):
        digest.update(str(part).encode())
    return digest.hexdigest()[:16]


def _marker(build: str) -> Path:
    return _cache_dir() / f"pour_gym_kernel_{build}_{_key()}.ready"


def _lock(build: str) -> Path:
    return _cache_dir() / f"pour_gym_kernel_{build}.lock"


def _cached(build: str) -> bool:
    if build in _known or _dispatcher(build).signatures:
        return True
    if _marker(build).is_file():
        _known.add(build)
        return True
    return False


def start(parallel: bool) -> None:
    """Have the builds a fluid needs compiled in a helper, unless they are cached.

    Returns at once. ``parallel``: the fluid runs on several threads (it needs both
    builds: the one-thread build serves until the threaded one is ready).
    """
    if not enabled():
        return
    wanted = ("serial", "parallel") if parallel else ("serial",)
    missing = tuple(b for b in wanted if not _cached(b))
    # Builds a helper has compiled or is still compiling.
    covered = {b for h in _helpers for b in h.builds if b in h.done or not h.finished.is_set()}
    missing = tuple(b for b in missing if b not in covered)
    if missing:
        # Two helpers when the one-thread build is missing: one compiles its walls part while
        # the other compiles the rest, then the driver (on two cores, 6 s instead of 9).
        groups = [("walls",), missing] if "serial" in missing else [missing]
        try:
            for group in groups:
                _helpers.append(_Helper(group))
        except OSError as error:  # no process to start: compile here
            _warn(f"could not start a helper process ({error})")


def ready(build: str, wait: bool) -> bool:
    """Whether a build can be called without compiling it here.

    Args:
        build: ``"serial"`` or ``"parallel"``.
        wait: wait for a helper that is compiling it.

    Returns:
        True if it is compiled (in this process, or in the cache), or if no helper will
        compile it (then the call compiles it, as numba does by itself); False if a helper
        is still compiling it and ``wait`` is false.
    """
    if _cached(build):
        return True
    for helper in _helpers:
        if build not in helper.builds:
            continue
        if wait:
            helper.reported[build].wait(WAIT_SECONDS)
        if build in helper.done:
            _known.add(build)
            return True
        if not helper.finished.is_set() and not wait:
            return False
        if helper.finished.is_set():
            code = helper.process.returncode
            _warn(f"the helper process compiling the fluid kernel failed (exit code {code})")
    return True


def wait_for_helpers(numba_cache: Path) -> None:
    """Wait for every helper (of any process) compiling into a numba cache to finish.

    Args:
        numba_cache: a ``NUMBA_CACHE_DIR``; its kernel locks are taken and released.
    """
    for lock in sorted(Path(numba_cache).rglob("pour_gym_kernel_*.lock")):
        with _locked(lock):
            pass


def _warn(message: str) -> None:
    if not _warned:
        _warned.append(True)
        warnings.warn(
            f"pour-gym: {message}; the fluid kernel is compiled in this process instead "
            f"(set {ENV_SWITCH}=0 to do so without trying).",
            RuntimeWarning,
            stacklevel=3,
        )


def _tiny_fluid(threads: int):
    """A few particles over a slab (no mesh, no open3d): enough to compile with."""
    import numpy as np

    from pour_gym.fluid.pbf import PBFluid
    from pour_gym.fluid.sdf import SignedDistanceField

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
    calls pass the types the driver passes (``tests/test_fluid.py`` checks that compiling
    the driver after both parts compiles none of them again).

    Args:
        part: ``"walls"`` (collisions with the containers' fields) or ``"constraint"`` (the
            cell sort, neighbour search, density constraint, velocities and poses).
    """
    import numpy as np

    from pour_gym.fluid import pbf

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
            with _locked(walls_lock):
                pass
    _tiny_fluid(2 if build == "parallel" else 1).step(1 / 60)


@contextlib.contextmanager
def _locked(path: Path):
    """Hold an exclusive lock on a file (released when the process ends, however it ends)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: helpers started together may compile twice
        fcntl = None
    with open(path, "a") as handle:
        if fcntl is not None:
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield


def main(builds: list[str]) -> int:
    """Compile the builds named, in order, each under its lock; print each when done."""
    unknown = [b for b in builds if b not in (*BUILDS, "walls")]
    if unknown:
        sys.stderr.write(f"unknown builds {unknown}; choose from {BUILDS} and walls\n")
        return 2
    directory = _cache_dir()
    if directory is None:
        return 1
    directory.mkdir(parents=True, exist_ok=True)
    import time

    for build in builds:
        with _locked(_lock(build)):
            if _marker(build).is_file():
                sys.stderr.write(f"pour-gym precompile: {build} found in the cache\n")
            else:
                start = time.perf_counter()
                compile_build(build, walls_lock=_lock("walls"))
                _marker(build).touch()
                seconds = time.perf_counter() - start
                sys.stderr.write(f"pour-gym precompile: {build} compiled in {seconds:.1f} s\n")
        print(build, flush=True)
    return 0
