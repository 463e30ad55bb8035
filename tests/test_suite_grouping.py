"""The suite's own scheduling: tests sharing a module fixture reach pytest-xdist as one group
(tests/conftest.py), so the fixture is built once per run, not once per test process."""

import pytest


@pytest.fixture(scope="module")
def shared():
    return object()


def test_a_test_with_a_module_fixture_carries_its_module_group(request, shared):
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("only an xdist worker running --dist loadgroup groups tests")
    assert request.node.nodeid.endswith("@" + __name__), request.node.nodeid
