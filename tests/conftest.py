"""Shared fixtures: Taichi runs once per test process, on the CPU (CI has no GPU), or on the
backend ``SANDBOX_TEST_ARCH`` names (tests/helpers.TEST_ARCH).

Plain helpers (scene dicts, state comparisons) live in tests/helpers.py; the names below are
re-exported for test files that import them from here.
"""

import os

import pytest

from tests.helpers import TEST_ARCH, box_body, plane, scene_dict  # noqa: F401  (re-exported, see above)

os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")


@pytest.fixture(scope="session", autouse=True)
def taichi_cpu():
    from sandbox import backend

    return backend.init(TEST_ARCH)


MAX_TEST_WORKERS = 4
"""Each test process holds its own Taichi runtime (~1.5-3 GB) and compiles its own kernels;
past four the memory grows faster than the suite shortens."""


def pytest_xdist_auto_num_workers(config):
    return max(1, min(os.cpu_count() or 1, MAX_TEST_WORKERS))


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups off the marks
def pytest_collection_modifyitems(config, items):
    """Tests sharing a module-scoped fixture (a bench run, a web server, a recorded scene) run
    in one process, so the fixture is built once; every other test is spread on its own."""
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        if any(d.scope == "module" for defs in info.name2fixturedefs.values() for d in defs):
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))


@pytest.hookimpl(tryfirst=True)  # before the xdist worker sends its collection to the controller
def pytest_collection_finish(session):
    """Make the groups reach xdist's scheduler. pytest-xdist 3.8 passes a test's group to the
    controller as an ``@group`` suffix written into ``item._nodeid``; pytest 9.2 keeps node ids in
    ``item._id`` and ignores that write (pytest-xdist issue #1386), so every test was scheduled on
    its own and each module fixture (the bench run, the recorded scene...) was built once per
    process. Where the suffix did not take, write it where this pytest reads it."""
    if not getattr(session.config.option, "loadgroup", False):  # set on xdist workers only
        return
    for item in session.items:
        mark = item.get_closest_marker("xdist_group")
        if mark is None or item.nodeid.rfind("@") > item.nodeid.rfind("]"):  # xdist's own test
            continue
        nodeid = f"{item.nodeid}@{mark.args[0]}"
        if hasattr(item, "_id"):
            from _pytest.nodeid import NodeId

            item._id = NodeId.parse(nodeid)
        else:
            item._nodeid = nodeid


def pytest_addoption(parser):
    parser.addoption("--stress", action="store_true", default=False,
                     help="run the long checks too: the whole hard-case matrix (every solver, 4 and 15 "
                          "iterations) and the long runs")


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
