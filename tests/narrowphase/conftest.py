"""Fixtures for the narrowphase tests: Taichi through sandbox.backend (CPU unless
SANDBOX_TEST_ARCH says otherwise, like tests/conftest.py) and one shared harness."""

import os

import pytest

from sandbox import backend


@pytest.fixture(scope="session")
def harness():
    backend.init(os.environ.get("SANDBOX_TEST_ARCH", "cpu"))
    from .harness import Harness

    return Harness()
