"""The fluid kernel compiled in a helper process, once per machine, while the world is built.

Numba compiles the kernel on its first call and keeps it in its on-disk cache (``cache=True``),
from which every later process loads it in a fraction of a second. The compile itself takes
seconds for the one-thread build and as long again for the threaded one, and a new process
would spend them inside its first ``step``. Instead, a :class:`~pour_gym.fluid.PBFluid` asks
for its build when it is created (:func:`start`): if that build is not known to be cached, a
helper process (:mod:`pour_gym.fluid.compile_helper`) compiles it into the cache while
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
                "import sys; from pour_gym.fluid.compile_helper import main; "
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
        and cache_dir() is not None
    )


def _dispatcher(build: str):
    """A build's numba dispatcher (the kernel is imported, not compiled, on the first call)."""
    from pour_gym.fluid.build import builds  # the kernel's source: only once a fluid exists

    return builds()[build]


def cache_dir() -> Path | None:
    """The directory numba caches the kernel in (``None`` if it cannot tell)."""
    try:
        return Path(_dispatcher("serial")._cache._cache_path)
    except (AttributeError, KeyError):  # another numba, or no kernel built: no helpers
        return None


def _key() -> str:
    """What a cached build depends on: the kernel's source, numba, Python and the CPU."""
    import llvmlite.binding as llvm

    here = Path(__file__).parent
    digest = hashlib.sha256()
    for name in ("kernel.py", "build.py", "sdf.py"):
        digest.update((here / name).read_bytes())
    features = nb.config.CPU_FEATURES  # numba's target: the host's, or POUR_GYM_CPU's
    for part in (
        nb.__version__,
        sys.version,
        platform.machine(),
        nb.config.CPU_NAME or llvm.get_host_cpu_name(),
        llvm.get_host_cpu_features().flatten() if features is None else features,
    ):
        digest.update(str(part).encode())
    return digest.hexdigest()[:16]


def marker(build: str) -> Path:
    """The file that marks a build as compiled into the cache."""
    return cache_dir() / f"pour_gym_kernel_{build}_{_key()}.ready"


def lock(build: str) -> Path:
    """The file a helper locks while it compiles a build."""
    return cache_dir() / f"pour_gym_kernel_{build}.lock"


def _cached(build: str) -> bool:
    if build in _known or _dispatcher(build).signatures:
        return True
    if marker(build).is_file():
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
        # A helper per build: two cores compile the two builds at once.
        try:
            for build in missing:
                _helpers.append(_Helper((build,)))
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
        with locked(lock):
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


@contextlib.contextmanager
def locked(path: Path):
    """Hold an exclusive lock on a file (released when the process ends, however it ends)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: helpers started together may compile twice
        fcntl = None
    with open(path, "a") as handle:
        if fcntl is not None:
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield
