"""The fluid kernel compiled in helper processes: once per cache, and nothing lost if not."""

import os
import re
import subprocess
import sys

import pytest

from pour_gym.fluid import compile_helper, precompile

HELPER = "import sys; from pour_gym.fluid.compile_helper import main; sys.exit(main(sys.argv[1:]))"


def _helper(cache, *builds) -> subprocess.Popen:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), precompile.ENV_SWITCH: "0"}
    return subprocess.Popen(
        [sys.executable, "-c", HELPER, *builds],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_unknown_builds_are_refused(capsys):
    assert compile_helper.main(["fastest"]) == 2
    assert "unknown builds ['fastest']" in capsys.readouterr().err


def test_switched_off_no_helper_starts_and_the_kernel_compiles_where_it_runs(monkeypatch):
    monkeypatch.setenv(precompile.ENV_SWITCH, "0")
    monkeypatch.setattr(precompile, "_helpers", [])
    precompile.start(parallel=True)
    assert precompile._helpers == []
    assert precompile.ready("parallel", wait=False)


def test_a_failing_helper_leaves_the_compile_to_this_process(monkeypatch):
    """A helper that dies reports nothing; the fluid then compiles its kernel itself."""
    monkeypatch.setattr(sys, "executable", "false")  # exits at once, with status 1
    helper = precompile._Helper(("serial",))
    assert helper.finished.wait(30)
    assert helper.done == set() and helper.process.returncode == 1
    monkeypatch.setattr(precompile, "_helpers", [helper])
    monkeypatch.setattr(precompile, "_cached", lambda build: False)
    monkeypatch.setattr(precompile, "_warned", [])
    with pytest.warns(RuntimeWarning, match="failed .exit code 1.; the fluid kernel is compiled"):
        assert precompile.ready("serial", wait=True)


@pytest.mark.slow
def test_helpers_started_together_compile_a_build_once(tmp_path):
    """Two processes' helpers for the same cache: one compiles, the other waits and finds
    it compiled (as the workers of a vector env do)."""
    helpers = [_helper(tmp_path, "serial") for _ in range(2)]
    outputs = [h.communicate(timeout=600) for h in helpers]
    assert [h.returncode for h in helpers] == [0, 0]
    assert [out.strip() for out, _ in outputs] == ["serial", "serial"]
    reports = sorted(re.search(r"precompile: (serial \w+)", err).group(1) for _, err in outputs)
    assert reports == ["serial compiled", "serial found"]


# A cylinder cup of 2000 particles tilted to 100 degrees over two seconds (it pours out onto
# the table: walls, floor and free surface all take part), on one thread and on two; prints
# the particles' hash on each and how many drivers this process compiled.
TILTING_POUR = """
import hashlib, numpy as np
from pour_gym.fluid import PBFConfig, PBFluid, build, build_sdf
from pour_gym.objects import cylinder_cup
R, H, W, B = 0.036, 0.10, 0.004, 0.006
field = build_sdf(cylinder_cup(R, H, W, B), spacing=0.001)
g = np.arange(-R + 0.0025, R, 0.005)
z = np.arange(B + 0.0025, H - 0.01, 0.005)
pts = np.stack(np.meshgrid(g, g, z, indexing="ij"), -1).reshape(-1, 3)
pts = pts[np.hypot(pts[:, 0], pts[:, 1]) < R - 0.0025]
pts = pts[np.lexsort((pts[:, 1], pts[:, 0], pts[:, 2]))][:2000]
hashes = []
for threads in (1, 2):
    fluid = PBFluid(pts, PBFConfig(), num_threads=threads, floor=0.0)
    fluid.wait_for_kernel()
    assert fluid.build == ("serial" if threads == 1 else "parallel")
    cup = fluid.add_collider(field, translation=np.array([0.0, 0.0, 0.05]))
    for k in range(20):
        a = np.radians(min(100.0, 6.0 * k))
        cup.rotation = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        fluid.step(0.1)
    hashes.append(hashlib.sha256(fluid.x.tobytes()).hexdigest())
misses = sum(sum(d.stats.cache_misses.values()) for d in build.builds().values())
print(*hashes, misses)
"""


@pytest.mark.slow
def test_every_build_of_the_kernel_pours_the_same_particles(tmp_path):
    """The kernel compiled by the helpers, compiled in the process that steps, and loaded
    from numba's cache by a later process gives the same particles bit for bit, on one
    thread and on two, in a pour that tilts (walls, floor, free surface). Before the parts
    were kept out of the cache (``pour_gym.fluid.sdf.PART_CACHE``), the helpers' build
    differed from the other in its last bits: a cup at rest did not show it."""

    def pour(cache, helpers):
        env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), precompile.ENV_SWITCH: helpers}
        done = subprocess.run(
            [sys.executable, "-c", TILTING_POUR], env=env, capture_output=True, text=True
        )
        assert done.returncode == 0, done.stderr[-2000:]
        one, two, misses = done.stdout.split()
        return one, two, int(misses)

    helpers = pour(tmp_path / "a", helpers="1")
    in_process = pour(tmp_path / "b", helpers="0")
    assert in_process[2] == 2, "the process did not compile both builds itself"
    assert list((tmp_path / "b").rglob("*.nbi")), "the process wrote no cache"
    cached = pour(tmp_path / "b", helpers="0")
    assert cached[2] == 0, "a process with a warm cache compiled the kernel again"
    assert pour(tmp_path / "a", helpers="0")[2] == 0
    assert helpers[0] == helpers[1], "one thread and two threads poured differently"
    assert in_process[:2] == helpers[:2], "the helpers' build and the in-process build differ"
    assert cached[:2] == helpers[:2], "the cached build differs from the compiled one"


def test_pour_gym_cpu_pins_the_processor_numba_compiles_for():
    """POUR_GYM_CPU names the processor every compiled function targets (its features
    alone, none of the host's); set after numba compiled something, it warns instead."""
    script = (
        "import warnings; warnings.simplefilter('error')\n"
        "import pour_gym\n"
        "from numba.core.registry import cpu_target\n"
        "print(*cpu_target.target_context.codegen().magic_tuple()[1:], sep='|')\n"
    )
    env = {**os.environ, "POUR_GYM_CPU": "x86-64-v2"}
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "x86-64-v2|"
    late = "import numba\nnumba.njit(lambda x: x)(1)\n" + script.replace("'error'", "'always'")
    done = subprocess.run([sys.executable, "-c", late], env=env, capture_output=True, text=True)
    assert "POUR_GYM_CPU=x86-64-v2 cannot take effect" in done.stderr
