"""Fixtures for the narrowphase tests: Taichi through sandbox.backend (CPU unless
SANDBOX_TEST_ARCH says otherwise, like tests/conftest.py) and one shared harness."""

import os

import pytest

from sandbox import backend

# harness.assert_points asserts for the test files: let pytest explain its failures as theirs
pytest.register_assert_rewrite("tests.narrowphase.harness")


@pytest.fixture(scope="session")
def harness():
    backend.init(os.environ.get("SANDBOX_TEST_ARCH", "cpu"))
    from .harness import Harness

    return Harness()
