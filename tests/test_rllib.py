"""RLlib trains on the pour-gym envs as they are: PPO with env runners in their own processes.

``ray[rllib]`` pins Gymnasium 1.2.2 and the suite runs on 1.4, so this runs in the second
virtual environment ``make test`` builds (``.venv-rllib``, ``make install-rllib``).
"""

import json
import subprocess
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RLLIB_PYTHON = ROOT / ".venv-rllib" / "bin" / "python"

needs_rllib = pytest.mark.skipif(
    not RLLIB_PYTHON.is_file(),
    reason="no .venv-rllib: `make install-rllib` (or `make test`) builds it",
)


def _ppo(env_id: str, runners: int) -> dict:
    # A short folder of our own for Ray's session (its socket paths must stay short).
    with tempfile.TemporaryDirectory(prefix="rl", dir="/tmp") as temp:
        done = subprocess.run(
            [str(RLLIB_PYTHON), "-m", "pour_gym.agents.training.rllib", "--env", env_id,
             "--env-runners", str(runners), "--batch-size", "128", "--ray-temp-dir", temp,
             "--json"],
            capture_output=True, text=True, timeout=600, cwd=ROOT,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
        # Nothing of that Ray instance is left running.
        ps = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
        assert temp not in ps
    return json.loads(done.stdout)


@needs_rllib
@pytest.mark.slow
def test_ppo_one_iteration_on_tilt_pour_with_two_env_runners():
    doc = _ppo("PourGym/TiltPour-v0", 2)
    assert doc["gymnasium"].startswith("1.2") and doc["env_steps_sampled"] >= 128
    assert doc["episodes"] >= 128  # one step an episode
    pids = {r["pid"] for r in doc["runners"]}
    assert len(pids) == 2 and doc["driver_pid"] not in pids
    # Ray gives a one-CPU worker OMP_NUM_THREADS=1, and the fluid takes one thread there.
    assert all(r["fluid_threads"] == 1 for r in doc["runners"])


@needs_rllib
@pytest.mark.slow
def test_ppo_one_iteration_on_pour_with_one_env_runner():
    doc = _ppo("PourGym/Pour-v0", 1)
    assert doc["env_steps_sampled"] >= 128
    assert [r["fluid_threads"] for r in doc["runners"]] == [1]
    assert doc["runners"][0]["pid"] != doc["driver_pid"]


def test_a_missing_rllib_ends_with_the_extra_named():
    import sys

    # Ray made unimportable, as where the extra is not installed.
    code = (
        "import sys; sys.modules['ray'] = None; from pour_gym.agents.training.rllib import main; "
        "sys.exit(main(['--env', 'PourGym/TiltPour-v0']))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 2 and "pour-gym[rllib]" in done.stderr
