"""Shared fixtures: the thesis objects are built once per test session."""

import pytest

from pour_gym.objects import OBJECT_NAMES, build_object


@pytest.fixture(scope="session")
def models():
    return {name: build_object(name) for name in OBJECT_NAMES}
