"""Shared fixtures: Taichi runs once per test process, on the CPU (CI has no GPU).

Plain helpers (scene dicts, state comparisons) live in tests/helpers.py; the names below are
re-exported for test files that import them from here.
"""

import os

import pytest

from tests.helpers import box_body, plane, scene_dict  # noqa: F401  (re-exported, see above)

os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")


@pytest.fixture(scope="session", autouse=True)
def taichi_cpu():
    from sandbox import backend

    return backend.init(os.environ.get("SANDBOX_TEST_ARCH", "cpu"))


def pytest_addoption(parser):
    parser.addoption("--stress", action="store_true", default=False,
                     help="run the long checks too: the whole hard-case matrix (every solver, 4 and 15 "
                          "iterations), the long runs, and every row of the state-hash record (tests/README.md)")


@pytest.fixture(scope="session")
def coacd_cache(tmp_path_factory):
    """A CoACD cache directory shared by the tests of one session (never the user's cache):
    every mesh is decomposed once per session, and cache hits are measured against it."""
    path = tmp_path_factory.mktemp("sandbox-cache")
    before = os.environ.get("SANDBOX_CACHE")
    os.environ["SANDBOX_CACHE"] = str(path)
    yield path
    if before is None:
        os.environ.pop("SANDBOX_CACHE", None)
    else:
        os.environ["SANDBOX_CACHE"] = before
