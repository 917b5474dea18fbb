"""Fixtures the tests share: the thesis objects, quick environments, the command line."""

import subprocess
import sys

import pytest

from pour_gym.envs import entry, make
from pour_gym.objects import OBJECT_NAMES, build_object


@pytest.fixture(scope="session")
def models():
    """The nine thesis objects, built once per test session."""
    return {name: build_object(name) for name in OBJECT_NAMES}


@pytest.fixture
def make_env():
    """``gymnasium.make`` with the id's quick arguments (its registry entry's ``quick``:
    small fluids), the test's arguments winning; every env made is closed afterwards."""
    made = []

    def _make(env_id: str, **kwargs):
        env = make(env_id, **{**entry(env_id).quick, **kwargs})
        made.append(env)
        return env

    yield _make
    for env in made:
        env.close()


def run_cli(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    """``pour-gym ARGS`` in a new process; with ``check``, exit status 0 is asserted."""
    proc = subprocess.run(
        [sys.executable, "-m", "pour_gym.apps.cli", *args], capture_output=True, text=True
    )
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


@pytest.fixture
def cli():
    """Run ``pour-gym`` in a new process (:func:`run_cli`)."""
    return run_cli
