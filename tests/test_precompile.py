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
    helpers = [_helper(tmp_path, "walls") for _ in range(2)]
    outputs = [h.communicate(timeout=600) for h in helpers]
    assert [h.returncode for h in helpers] == [0, 0]
    assert [out.strip() for out, _ in outputs] == ["walls", "walls"]
    reports = sorted(re.search(r"precompile: (walls \w+)", err).group(1) for _, err in outputs)
    assert reports == ["walls compiled", "walls found"]


@pytest.mark.slow
def test_the_parts_compiled_apart_are_the_ones_the_driver_calls(tmp_path):
    """The one-thread build compiled in two parts by two processes: the driver, compiled
    after both, loads the walls part and adds no second version of any function (the parts
    were called with the types the driver passes)."""
    walls = _helper(tmp_path, "walls")
    assert walls.communicate(timeout=600)[0].strip() == "walls"
    script = (
        "import gc\n"
        "from numba.core.registry import CPUDispatcher\n"
        "from pour_gym.fluid import compile_helper\n"
        "compile_helper.compile_build('serial')\n"
        "for d in gc.get_objects():\n"
        "    if isinstance(d, CPUDispatcher) and d.signatures:\n"
        "        misses = sum(d.stats.cache_misses.values())\n"
        "        print(d.py_func.__qualname__, len(d.signatures), misses)\n"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), precompile.ENV_SWITCH: "0"}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
    )
    lines = (line.split() for line in done.stdout.splitlines())
    rows = {name: (int(n), int(m)) for name, n, m in lines}
    for name in ("_pass_collide", "_wall_term"):
        assert rows[name] == (1, 0), f"{name} was compiled again, not loaded"
    for name in ("_lambda_run", "_correct_run", "_finish_run", "_sort_cells", "_pose_at"):
        assert rows[name][0] == 1, f"{name} has a second version: the part passed other types"
    assert rows["_advance_serial"] == (1, 1)
