"""Shared fixtures: the thesis objects are built once per test session."""

import warnings

import pytest

from pour_gym.objects import OBJECT_NAMES, build_object

# numba warns once that the machine's TBB is too old and falls back to OpenMP/workqueue.
warnings.filterwarnings("ignore", message=".*TBB.*")


@pytest.fixture(scope="session")
def models():
    return {name: build_object(name) for name in OBJECT_NAMES}
